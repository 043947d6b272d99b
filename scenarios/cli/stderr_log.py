"""The command line's diagnostics on stderr (docs/cli.md): the records of the ``impactqp``
logger hierarchy, one plain line each.

The library logs through ``logging.getLogger(__name__)`` in each module and never configures a
handler; only the command line does, for the time of one command (:func:`log_to_stderr`), at the
level of the group's options: ``--verbose`` DEBUG, none INFO (notes and progress), ``--quiet``
WARNING (warnings and errors only, and no progress bars: :func:`show_progress`). Results
(tables, JSON) go to stdout with ``click.echo`` and never through the log. The bad-input and
internal-error lines are ``scenarios.cli.main``'s own, not log records.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable

LOGGER = "impactqp"
"""The root of the package's logger hierarchy (every module's ``logging.getLogger(__name__)``)."""


class StderrHandler(logging.StreamHandler):
    """A stream handler that writes to ``sys.stderr`` as it is when a record comes (a stream
    replaced after the handler was made, e.g. a captured one, is the one written to)."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        """Ignored: the stream is always the current ``sys.stderr``."""


class OneLineFormatter(logging.Formatter):
    """``impactqp: MESSAGE`` for a note (INFO), ``impactqp: LEVEL: MESSAGE`` otherwise; the
    message's whitespace folded to single spaces, so that a record is one line."""

    def format(self, record: logging.LogRecord) -> str:
        level = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        return f"impactqp: {level}" + " ".join(record.getMessage().split())


def log_to_stderr(level: int) -> Callable[[], None]:
    """Send the records of the ``impactqp`` hierarchy at ``level`` and above to stderr, one line
    each; returns the function that removes the handler and restores the level."""
    logger = logging.getLogger(LOGGER)
    handler = StderrHandler()
    handler.setFormatter(OneLineFormatter())
    previous = logger.level
    logger.setLevel(level)
    logger.addHandler(handler)

    def remove() -> None:
        logger.removeHandler(handler)
        logger.setLevel(previous)

    return remove


def show_progress(as_json: bool = False) -> bool:
    """Whether a command draws progress bars (on stderr, and only on a terminal): not with
    ``--json``, and not with ``--quiet`` (progress is a note: INFO)."""
    return not as_json and logging.getLogger(LOGGER).isEnabledFor(logging.INFO)
