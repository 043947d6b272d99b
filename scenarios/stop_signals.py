"""Stop signals: during ``impactqp run`` (``scenarios.run``) Ctrl-C, SIGTERM or SIGHUP brakes the
running loop to a stop instead of ending the process, so the log is kept and the robot stops
within its limits."""

from __future__ import annotations

import signal
import threading
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # light to import: the command line reads STOP_SIGNALS before anything heavy
    from impactqp.controller.runtime.loop import ControlLoop

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that stop a command (the command line's ``main``) or brake a running loop."""


class StopSignals:
    """While active (in the main thread only: signal handlers can be set nowhere else), Ctrl-C,
    SIGTERM or SIGHUP asks the current ``loop`` to brake to a stop; a signal the parent set to be
    ignored (``nohup``, a background job) stays ignored, as in the command line's ``main``. A stop
    that comes while no loop runs (before the first, between two) is kept: every loop set after
    it is asked to stop at once (``stopped``)."""

    def __init__(self):
        self._loop: ControlLoop | None = None
        self.stopped = False
        self.previous: dict = {}

    @property
    def loop(self) -> ControlLoop | None:
        return self._loop

    @loop.setter
    def loop(self, loop: ControlLoop | None) -> None:
        self._loop = loop
        if self.stopped and loop is not None:
            loop.request_stop()

    def request_stop(self, *_) -> None:
        self.stopped = True
        if self._loop is not None:
            self._loop.request_stop()

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            self.previous = {
                sig: signal.signal(sig, self.request_stop)
                for sig in STOP_SIGNALS
                if signal.getsignal(sig) is not signal.SIG_IGN
            }
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)

