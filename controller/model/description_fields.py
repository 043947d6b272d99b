"""Reading the fields of a robot description file (``robot_description``,
``held_contact_description``): names, lists of names and tables, each checked, bad input as one
line (``BadInputError``)."""

from __future__ import annotations

from collections.abc import Mapping

from .validation import BadInputError

MAX_JOINTS = 256
"""The most moving joints a description may have (a humanoid has a few dozen)."""


def names_field(value, what: str) -> tuple[str, ...]:
    """``value``: a list of at most :data:`MAX_JOINTS` distinct non-empty names."""
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise BadInputError(f"{what} must be a list of names")
    if len(value) > MAX_JOINTS or len(set(value)) != len(value):
        raise BadInputError(f"{what} must hold at most {MAX_JOINTS} distinct names")
    return tuple(value)


def name_field(value, what: str) -> str:
    """``value``: a non-empty name."""
    if not isinstance(value, str) or not value:
        raise BadInputError(f"{what} must be a non-empty name")
    return value


def table_field(data: Mapping, key: str, keys: set[str], what: str) -> dict:
    """``data[key]``: a table whose keys are among ``keys`` (empty when missing)."""
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise BadInputError(f"{what} [{key}] must be a table")
    unknown = sorted(set(value) - keys)
    if unknown:
        raise BadInputError(f"{what} [{key}]: unknown keys {', '.join(unknown)}; known: {', '.join(sorted(keys))}")
    return value


def named_tables_field(data: Mapping, key: str, robot: str) -> dict:
    """``data[key]``: a table of named tables (postures, stances), empty when missing."""
    value = data.get(key, {})
    if not isinstance(value, dict) or not all(isinstance(v, dict) for v in value.values()):
        raise BadInputError(f"the {robot} [{key}] must be a table of named tables")
    return value
