"""``scenarios.stop_signals``: a stop signal during a run brakes the loop, and the handlers are
restored after it."""

import os
import signal

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
