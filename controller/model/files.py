"""The one reader of the user's configuration and data files (JSON, TOML, YAML).

Every failure is bad input with one line that names the file: a missing file, anything but a
regular file (a directory, a FIFO, a device: checked before the file is opened, so a FIFO never
blocks the reader), a file larger than ``MAX_FILE_BYTES``, text that is not UTF-8 (a byte-order
mark is accepted), a syntax error, nesting deeper than the parser's recursion allows, a document
that is not a table of keys and values, an integer beyond ``MAX_INTEGER`` (no physical quantity,
count or seed of ours is one: checked before any conversion, so a number of thousands of digits is
one line, not an overflow), a YAML alias (an alias repeats a node: nested aliases expand a
small file into gigabytes), or a key given twice in one table (TOML refuses it itself; JSON and
YAML parsers would keep the last value silently).
"""

from __future__ import annotations

import json
import os
import stat
import tomllib
from pathlib import Path

import yaml

from .validation import BadInputError, repeated

MAX_FILE_BYTES = 256 * 2**20
"""Largest file read (bytes): far above any configuration or manifest of ours (a manifest entry
takes a few hundred bytes), far below what would exhaust the memory."""

SYNTAXES = {".json": "json", ".toml": "toml", ".yaml": "yaml", ".yml": "yaml"}
"""The syntax of a file by its suffix, when the caller does not choose one."""

MAPPING = {"json": "a JSON object", "toml": "a table of keys and values", "yaml": "a table of keys and values"}

_PARSE_ERRORS = (json.JSONDecodeError, tomllib.TOMLDecodeError, yaml.YAMLError)
MAX_INTEGER = 2**63
"""Largest |integer| in a file (a signed 64-bit integer's range)."""
MAX_INTEGER_DIGITS = len(str(MAX_INTEGER))


class _NoAliasLoader(yaml.SafeLoader):
    """PyYAML's safe loader without aliases and without a key given twice in one mapping (module
    docstring)."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, "YAML aliases (*name) are not accepted", event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if not isinstance(key, (str, int, float, bool)):  # a key made of a list or a table is not compared
                continue
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"the key {key!r} is given twice", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


class _RepeatedKeyError(ValueError):
    """A JSON object that gives one key twice."""


def _json_object(pairs: list) -> dict:
    """A JSON object; _RepeatedKeyError when a key is given twice (json would keep the last one)."""
    twice = repeated(key for key, _ in pairs)
    if twice:
        raise _RepeatedKeyError(f"the key {twice[0]!r} is given twice")
    return dict(pairs)


def _json_integer(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits")
    return int(text)


def _out_of_range_integer(value) -> int | None:
    """The first integer of the parsed document beyond MAX_INTEGER (None when there is none)."""
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, int) and not isinstance(item, bool) and abs(item) > MAX_INTEGER:
            return item
    return None


def regular_file(
    path: str | Path, what: str, error: type[BadInputError] = BadInputError, shown: str | None = None
) -> Path:
    """``path`` as a Path after checking, without opening it, that it names a regular file;
    else ``error`` (a :class:`BadInputError`) whose message starts with ``what`` and the path
    (or ``shown`` in its place)."""
    path = Path(path)
    name = f"{what} {path if shown is None else shown}".strip()
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise error(f"{name} does not exist") from None
    except NotADirectoryError:
        raise error(f"{name} does not exist (a parent is not a directory)") from None
    except OSError as failure:
        raise error(f"cannot read {name}: {failure.strerror or failure}") from None
    if stat.S_ISDIR(mode):
        raise error(f"{name} is a directory, not a file")
    if not stat.S_ISREG(mode):
        raise error(f"{name} is not a regular file (a FIFO, a socket or a device)")
    return path


def read_text(path: str | Path, what: str, error: type[BadInputError] = BadInputError) -> str:
    """The UTF-8 text of the regular file ``path`` (at most ``MAX_FILE_BYTES``)."""
    path = regular_file(path, what, error)
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except OSError as failure:
        raise error(f"cannot read {what} {path}: {failure.strerror or failure}") from None
    if len(data) > MAX_FILE_BYTES:
        raise error(f"{what} {path} is larger than {MAX_FILE_BYTES} bytes")
    try:
        return data.decode("utf-8-sig")  # a byte-order mark is not an error
    except UnicodeDecodeError:
        raise error(f"{what} {path} is not a UTF-8 text file") from None


def read_mapping(
    path: str | Path, what: str, syntax: str | None = None, error: type[BadInputError] = BadInputError
) -> dict:
    """The table of keys and values in the file ``path``, parsed as ``syntax`` ('json', 'toml'
    or 'yaml'; by default by the suffix, see ``SYNTAXES``). An empty YAML document is an empty
    table. Every failure raises ``error`` (module docstring)."""
    path = Path(path)
    syntax = syntax or SYNTAXES.get(path.suffix.lower())
    if syntax not in MAPPING:
        raise error(f"{what} {path}: unsupported file type; use {', '.join(SYNTAXES)}")
    text = read_text(path, what, error)
    try:
        if syntax == "json":
            value = json.loads(text, parse_int=_json_integer, object_pairs_hook=_json_object)
        elif syntax == "toml":
            value = tomllib.loads(text)
        else:
            value = yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - the safe loader, without aliases
            value = {} if value is None else value
    except RecursionError:
        raise error(f"{what} {path} is nested too deeply") from None
    except (*_PARSE_ERRORS, _RepeatedKeyError) as failure:
        raise error(f"{what} {path} is not valid {syntax.upper()}: {' '.join(str(failure).split())}") from None
    except ValueError as failure:  # an integer of thousands of digits (Python's int() limit)
        raise error(f"{what} {path} holds a number too large to read: {' '.join(str(failure).split())}") from None
    if not isinstance(value, dict):
        raise error(f"{what} {path} must be {MAPPING[syntax]}, got {type(value).__name__}")
    huge = _out_of_range_integer(value)
    if huge is not None:
        digits = len(str(abs(huge))) if huge.bit_length() < 10000 else "thousands of"
        raise error(f"{what} {path} holds an integer of {digits} digits, beyond +-2^63")
    return value
