"""The command line's log on stderr (``scenarios.cli.stderr_log``): one line per record, on the
stderr of the moment, the level of the group's options, removed after the command; the library
adds no handler."""

from __future__ import annotations

import io
import logging
import subprocess
import sys

from hypothesis import given
from hypothesis import strategies as st

from impactqp.scenarios.cli.stderr_log import LOGGER, OneLineFormatter, log_to_stderr, show_progress


def test_a_record_is_one_line_on_the_stderr_of_the_moment(monkeypatch):
    logger = logging.getLogger(f"{LOGGER}.sim.diagnosis.pipeline")
    remove = log_to_stderr(logging.INFO)
    try:
        captured = io.StringIO()
        monkeypatch.setattr(sys, "stderr", captured)  # replaced after the handler was made
        logger.info("diagnose: step %d/%d", 1, 5)
        logger.debug("not at INFO")
        logger.warning("two\nlines")
    finally:
        remove()
    assert captured.getvalue() == "impactqp: diagnose: step 1/5\nimpactqp: warning: two lines\n"


@given(st.text())
def test_every_message_formats_to_one_line_with_the_prefix(message):
    record = logging.LogRecord("impactqp.x", logging.ERROR, __file__, 1, "%s", (message,), None)
    line = OneLineFormatter().format(record)
    assert "\n" not in line and "\r" not in line and line.startswith("impactqp: error: ")
    assert line.removeprefix("impactqp: error: ").split() == message.split()


def test_removing_restores_the_logger_and_progress_follows_the_level():
    logger = logging.getLogger(LOGGER)
    before = (list(logger.handlers), logger.level)
    for level, progress in ((logging.DEBUG, True), (logging.INFO, True), (logging.WARNING, False)):
        remove = log_to_stderr(level)
        try:
            assert logger.getEffectiveLevel() == level and len(logger.handlers) == len(before[0]) + 1
            assert show_progress() is progress and show_progress(as_json=True) is False
        finally:
            remove()
        assert (list(logger.handlers), logger.level) == before


def test_importing_the_package_and_its_commands_adds_no_handler():
    """The library never configures logging: after importing every command, neither the root
    logger nor the package's has a handler or a level."""
    script = (
        "import logging\n"
        "import impactqp.scenarios.cli.commands, impactqp.sim.diagnosis, impactqp.scenarios.bench\n"
        "loggers = [logging.getLogger(), logging.getLogger('impactqp')]\n"
        "loggers += [l for n, l in logging.Logger.manager.loggerDict.items()\n"
        "            if n.startswith('impactqp') and isinstance(l, logging.Logger)]\n"
        "assert all(l.handlers == [] for l in loggers), [(l.name, l.handlers) for l in loggers if l.handlers]\n"
        "assert logging.getLogger('impactqp').level == logging.NOTSET\n"
        "print(len(loggers))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout) > 2  # the modules' own loggers were found and checked
