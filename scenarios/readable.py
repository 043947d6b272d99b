"""Numbers as a person reads them, in the text outputs and the Markdown reports.

JSON output keeps full precision; the text beside it shows:

- vectors (contact points, impulses, joint positions) with a fixed number of decimals, never in
  scientific notation and never as ``-0.0000`` (:func:`fixed`);
- single values with 4 significant digits, in positional notation between 1e-4 and 1e6
  (:func:`number`; Python's ``g`` format switches to an exponent below 1e-4 by itself);
- plant overrides with their units, grouped as the diagnosis fits them: a per-joint vector that is
  constant over each of the Panda's drive groups (joints 1-4 and 5-7,
  ``sim.causes.joint_groups``) as one value per group (:func:`parameters_text`);
- booleans as in JSON, ``true`` / ``false`` (:func:`boolean`).
"""

from __future__ import annotations

import numpy as np

from impactqp.sim.causes import group_name, joint_groups
from impactqp.sim.plant import PER_JOINT, RANGES

DECIMALS = 4
SIGNIFICANT = 4
LARGEST_POSITIONAL = 1e6


def fixed(values, decimals: int = DECIMALS) -> str:
    """``[a, b, c]`` with ``decimals`` decimals each (a value that rounds to zero prints as 0)."""
    return "[" + ", ".join(_fixed(float(x), decimals) for x in np.ravel(values)) + "]"


def _fixed(x: float, decimals: int) -> str:
    text = f"{x:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def number(x: float) -> str:
    """``x`` with ``SIGNIFICANT`` significant digits, positional from 1e-4 to
    ``LARGEST_POSITIONAL`` (whole numbers from 10^SIGNIFICANT on), trailing zeros dropped."""
    x = float(x) + 0.0  # -0.0 prints as 0
    if 10.0**SIGNIFICANT <= abs(x) < LARGEST_POSITIONAL:
        return f"{x:.0f}"
    return f"{x:.{SIGNIFICANT}g}"


def boolean(value: bool) -> str:
    """``true`` or ``false``, as JSON writes it."""
    return "true" if value else "false"


def value_text(value, per_joint: bool = False) -> str:
    """One plant override: a number, a vector, or a per-joint vector (``per_joint``) by joint
    group when it is constant over each group."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return number(float(array))
    if per_joint and array.ndim == 1 and array.size >= 2:
        indices = joint_groups(array.size)
        groups = [array[list(g)] for g in indices]
        if all(np.all(g == g[0]) for g in groups):
            return ", ".join(f"{group_name(g)} = {number(v[0])}" for g, v in zip(indices, groups))
    return "[" + ", ".join(number(x) for x in array.ravel()) + "]"


def parameters_text(overrides: dict) -> str:
    """Plant overrides as ``key (unit): value; ...`` (``value_text``, units of
    ``sim.plant.RANGES``); ``nominal`` when empty."""
    return "; ".join(
        f"{key}{unit_text(key)}: {value_text(value, key in PER_JOINT)}" for key, value in overrides.items()
    ) or "nominal"


def unit_text(key: str) -> str:
    unit = RANGES.get(key, (None, None, ""))[2]
    return f" ({unit})" if unit else ""
