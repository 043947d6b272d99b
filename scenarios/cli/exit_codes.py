"""The exit codes of ``impactqp`` (docs/errors.md); a leaf module, so that the
entry point reads them before any heavy import."""

EXIT_INTERNAL_ERROR = 1
"""An internal error (a bug of ours); also ``dataset validate`` when it found problems."""
EXIT_BAD_INPUT = 2
"""Bad input: one line on stderr naming the input."""
EXIT_ROBOT_WOULD_STOP = 3
"""``impactqp run``: the watchdog or the overrun budget stopped the run, or would have stopped a real robot."""
EXIT_INTERRUPTED = 130
"""Ctrl-C, SIGTERM or SIGHUP."""
