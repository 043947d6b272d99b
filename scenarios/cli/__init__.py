"""The ``impactqp`` command line: it parses options and calls the library, nothing more.

One error boundary (:func:`main`):

- bad input (``BadInputError`` from the one validation module, a usage error, or an ``OSError``
  on a path the user gave) gets one line on stderr and exit code 2, never a traceback;
- anything else is an internal error: exit code 1 and one line that asks for a report; the
  traceback only with ``impactqp --debug``;
- ``impactqp run``: exit code 3 when the watchdog or the overrun budget stopped the run, or would
  have stopped a real robot;
- Ctrl-C, SIGTERM or SIGHUP ends with exit code 130, from the first instant of :func:`main`.
  The handler raises ``KeyboardInterrupt`` and re-raises it every :data:`REDELIVERY_PERIOD`
  (SIGALRM) until :func:`main` has caught it: code that swallows one (a library's
  ``try: import ... except ImportError`` around a C extension whose initialisation the signal
  interrupted) cannot make the command run on as if no signal had come.

This module is the console entry point and stays tiny: :func:`main` installs the signal handlers
first and only then imports the commands (numpy, Pinocchio, MuJoCo: seconds of imports), so a
signal during start-up is an interruption like any other. ``--json`` prints machine-readable
output on stdout; notes, progress and warnings go to stderr through the log, at the level of
``impactqp --verbose|--quiet`` (``scenarios.cli.stderr_log``, docs/cli.md).
"""

from __future__ import annotations

import signal
import sys
import traceback

from impactqp.scenarios.stop_signals import STOP_SIGNALS
from impactqp.scenarios.cli import command_result
from impactqp.scenarios.cli.exit_codes import (
    EXIT_BAD_INPUT,
    EXIT_INTERNAL_ERROR,
    EXIT_INTERRUPTED,
)

__all__ = ["main"]

REDELIVERY_PERIOD = 0.05
"""s between re-raisings of a stop signal's KeyboardInterrupt until ``main`` catches it."""
_interrupting = False  # a stop signal came and main has not caught its KeyboardInterrupt yet
_finishing = False  # main is past its command (its last line, its handlers): no interruption any more


def main(argv: list[str] | None = None) -> int:
    """Run the command line; the exit code: 0 done, 1 internal error (or problems found by
    ``dataset validate``), 2 bad input, 3 a run a real robot would not have finished, 130 Ctrl-C."""
    global _interrupting, _finishing
    args = sys.argv[1:] if argv is None else list(argv)
    _finishing = False
    command_result.new_command()
    # before anything else: cleanup (temporary files, the robot brake) runs on every stop signal,
    # and a signal during the imports below ends with exit code 130 too; a signal the parent set
    # to be ignored (nohup, a background job) stays ignored
    previous = {sig: signal.getsignal(sig) for sig in (*STOP_SIGNALS, signal.SIGALRM)}
    previous_hook, sys.unraisablehook = sys.unraisablehook, _drop_interruptions
    _interrupting = False
    # the handlers go in with the signals blocked, as one step: a signal sent once one of them is
    # in (as a parent watching them sees) waits for the others and then meets this try
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, previous)
    try:
        try:
            try:
                for sig, handler in previous.items():
                    if handler is not signal.SIG_IGN:
                        signal.signal(sig, _interrupt_again if sig == signal.SIGALRM else _interrupt)
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            return _run(args)
        except Exception as exc:  # noqa: BLE001 - the boundary
            if not interrupted(exc):
                return _report(exc, args)
            raise KeyboardInterrupt from None
    except KeyboardInterrupt:
        # first, with no call before them: no interruption and no re-raising from here on
        _finishing, _interrupting = True, False
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        for sig in STOP_SIGNALS:  # a second signal must not interrupt the last line
            signal.signal(sig, signal.SIG_IGN)
        sys.stderr.write("impactqp: interrupted\n")
        return EXIT_INTERRUPTED
    finally:
        _finishing, _interrupting = True, False  # a stop signal now would escape main as a traceback
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        sys.unraisablehook = previous_hook
        for sig, handler in previous.items():
            if argv is None and sig in STOP_SIGNALS:
                # the console entry point: the work is done and its exit code stands; a stop
                # signal during the interpreter's shutdown must not kill the process by the signal
                signal.signal(sig, signal.SIG_IGN)
            elif handler is not None:  # None: a handler not set from Python, which cannot be restored
                signal.signal(sig, handler)


def _run(args: list[str]) -> int:
    """The command of ``args``; its exit code."""
    # the command line's lazy loading: click, numpy and the commands load after the handlers
    import click

    from impactqp.scenarios.cli.commands import cli

    try:
        code = cli.main(args=args, prog_name="impactqp", standalone_mode=False)
    except click.exceptions.Abort:  # click's form of a KeyboardInterrupt
        raise KeyboardInterrupt from None
    return code if isinstance(code, int) else 0


def _report(exc: Exception, args: list[str]) -> int:
    """One line on stderr for an error that ended a command; its exit code."""
    # lazy: the command line loads what a command needs when it runs
    import click
    from impactqp.controller.model.validation import BadInputError

    if isinstance(exc, click.ClickException):
        click.echo(f"impactqp: error: {exc.format_message()}", err=True)
        return EXIT_BAD_INPUT
    if isinstance(exc, BadInputError):
        click.echo(f"impactqp: error: {_one_line(exc)}", err=True)
        return EXIT_BAD_INPUT
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"impactqp: error: {where}{exc.strerror or _one_line(exc)}", err=True)
        return EXIT_BAD_INPUT
    # anything else is our bug
    if "--debug" in args[: args.index("--") if "--" in args else len(args)]:
        traceback.print_exception(exc)
    click.echo(
        f"impactqp: internal error ({type(exc).__name__}: {_one_line(exc)}); please report it, "
        "with the output of the same command run as `impactqp --debug ...`",
        err=True,
    )
    return EXIT_INTERNAL_ERROR


def interrupted(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt (a stop signal) is in the chain of ``exc``: a C extension
    whose initialisation a signal interrupts turns it into an ImportError ("initialization
    failed"), and cleanup code may raise while one unwinds."""
    seen: set[int] = set()
    cause: BaseException | None = exc
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


def _drop_interruptions(unraisable) -> None:
    """``sys.unraisablehook`` while ``main`` runs: a stop signal's KeyboardInterrupt raised where
    Python cannot propagate it (a weakref callback, a finaliser: "Exception ignored in ...") is
    dropped without a word, since the handler raises it again until ``main`` catches it
    (``_interrupt_again``); anything else goes to Python's own hook."""
    if not (_interrupting and isinstance(unraisable.exc_value, KeyboardInterrupt)):
        sys.__unraisablehook__(unraisable)


def _interrupt(signum, frame):
    global _interrupting
    if _finishing or command_result.result_is_out():  # the command is over: its exit code stands
        return
    _interrupting = True
    signal.setitimer(signal.ITIMER_REAL, REDELIVERY_PERIOD, REDELIVERY_PERIOD)
    raise KeyboardInterrupt


def _interrupt_again(signum, frame):
    """SIGALRM: the stop signal's KeyboardInterrupt once more, until main has caught one."""
    if _interrupting:
        raise KeyboardInterrupt


def _one_line(exc: BaseException) -> str:
    text = str(exc.args[0]) if exc.args else str(exc)
    return " ".join(text.split()) or type(exc).__name__
