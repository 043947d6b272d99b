"""``scenarios.stop_signals``: a stop signal during a run brakes the loop, one that comes between
loops is kept, and the handlers are restored after it."""

import os
import signal

import pytest

from impactqp.scenarios.stop_signals import STOP_SIGNALS, StopSignals


def test_stop_signals_ask_the_loop_to_stop_and_leave_ignored_signals_ignored():
    """Inside ``StopSignals`` a stop signal asks the current loop to brake; a signal the parent
    ignored (nohup) stays ignored; every handler is restored on exit."""
    class Loop:
        stops = 0

        def request_stop(self):
            self.stops += 1

    before = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with StopSignals() as signals:
            signals.loop = loop = Loop()
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
            os.kill(os.getpid(), signal.SIGHUP)  # ignored: no stop
            os.kill(os.getpid(), signal.SIGTERM)
            assert loop.stops == 1
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) == before[signal.SIGTERM]
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)


class Loop:
    def __init__(self):
        self.stops = 0

    def request_stop(self):
        self.stops += 1


@pytest.mark.parametrize("sig", STOP_SIGNALS)
def test_a_stop_before_the_first_loop_or_between_two_stops_every_later_loop(sig):
    """A signal that comes while no loop runs (before the first, between the move to the start
    and the session) is not lost: each loop set after it is asked to stop at once."""
    with StopSignals() as signals:
        os.kill(os.getpid(), sig)
        signals.loop = first = Loop()
        signals.loop = second = Loop()
    assert signals.stopped and first.stops == 1 and second.stops == 1
    with StopSignals() as quiet:
        quiet.loop = untouched = Loop()
    assert not quiet.stopped and untouched.stops == 0
