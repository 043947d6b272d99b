"""Whether the running command's result is out: its JSON on stdout, from the moment it starts
to be written (``arguments.emit_json``).
From then on the work is done, and ``main`` lets a stop signal leave the command's exit code as
it is, as one that comes after ``main`` returns (docs/errors.md, "Stop signals")."""

from __future__ import annotations

_out = False


def result_written() -> None:
    """The command's result is out."""
    global _out
    _out = True


def result_is_out() -> bool:
    return _out


def new_command() -> None:
    """A command starts (``main``): no result yet."""
    global _out
    _out = False
