"""Shared by the tests of the command line (scenarios/cli/): one command run through ``main`` and
the shape of a bad-input answer."""

from __future__ import annotations

from impactqp.scenarios.cli import main


def run(capsys, *args):
    """``impactqp ARGS`` through ``main``: (exit code, stdout, stderr)."""
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def one_line_bad_input(code, out, err, fragment):
    """Bad input: exit code 2, one line on stderr holding ``fragment``, no traceback."""
    assert code == 2, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert fragment in err
