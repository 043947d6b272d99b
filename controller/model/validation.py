"""The one place that validates the physical inputs shared across the package.

Every caller that takes a surface normal, a restitution coefficient or a tangential velocity goes
through these functions, so each kind of input has one tolerance, one policy and one message.
Bad input raises :class:`BadInputError`; the command line turns it into one line on stderr and
exit code 2. Anything else that escapes is an internal error (exit code 1).
"""

from __future__ import annotations

import math

import numpy as np

NORMAL_MIN_NORM = 1e-9
"""A normal shorter than this cannot be normalised."""

MAX_CONTACT_SPEED = 3.0
"""Largest contact speed (m/s) accepted anywhere: the Panda's end effector tops out near 2 m/s."""

ORTHOGONALITY_TOLERANCE = 1e-6
"""Largest |v_t . n| (m/s) accepted for a tangential velocity; larger is rejected, never projected."""


class BadInputError(ValueError):
    """Input that the user can fix: a wrong value, shape, unit, file or request.

    The message is one line that names the offending input.
    """


def finite_vector(value, size: int | None, what: str) -> np.ndarray:
    """``value`` as a finite float vector of ``size`` entries (any size when None)."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{what} must be a vector of numbers") from exc
    if array.ndim != 1 or (size is not None and array.shape[0] != size):
        expected = f"{size} numbers" if size is not None else "a flat list of numbers"
        raise BadInputError(f"{what} must be {expected}, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise BadInputError(f"{what} must be finite, got {array.tolist()}")
    return array


def unit_normal(normal, what: str = "the surface normal") -> np.ndarray:
    """The normalised 3-vector ``normal``; a non-finite or (near-)zero normal is bad input."""
    n = finite_vector(normal, 3, what)
    norm = float(np.linalg.norm(n))
    if norm < NORMAL_MIN_NORM:
        raise BadInputError(f"{what} must be non-zero, got {n.tolist()}")
    return n / norm


def restitution(value, what: str = "the restitution") -> float:
    """The coefficient of restitution c_r, in [0, 1] (0: the contact sticks, 1: elastic)."""
    if isinstance(value, bool):
        raise BadInputError(f"{what} must be a number in [0, 1], got {value!r}")
    try:
        c_r = float(value)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{what} must be a number in [0, 1], got {value!r}") from exc
    if not (math.isfinite(c_r) and 0.0 <= c_r <= 1.0):
        raise BadInputError(f"{what} must lie in [0, 1], got {c_r}")
    return c_r


def approach_speed(value, what: str = "the approach speed") -> float:
    """An approach speed along -n in m/s, in (0, MAX_CONTACT_SPEED]."""
    if isinstance(value, bool):
        raise BadInputError(f"{what} must be a number of m/s, got {value!r}")
    try:
        speed = float(value)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{what} must be a number of m/s, got {value!r}") from exc
    if not (math.isfinite(speed) and 0.0 < speed <= MAX_CONTACT_SPEED):
        raise BadInputError(f"{what} must be > 0 and at most {MAX_CONTACT_SPEED} m/s, got {speed}")
    return speed


MIN_IMPACT_DURATION, MAX_IMPACT_DURATION = 1e-3, 0.1
"""s: an impact lasts at least one 1 kHz control period and far less than 0.1 s (the paper's
impacts last about 15 ms, 25 ms at most)."""


def impact_duration(value, what: str = "the impact duration") -> float:
    """The impact duration delta_t (s) of the impulsive-torque bound, in [1 ms, 100 ms]."""
    if isinstance(value, bool):
        raise BadInputError(f"{what} must be a number of seconds, got {value!r}")
    try:
        duration = float(value)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{what} must be a number of seconds, got {value!r}") from exc
    if not (math.isfinite(duration) and MIN_IMPACT_DURATION <= duration <= MAX_IMPACT_DURATION):
        raise BadInputError(
            f"{what} must lie in [{MIN_IMPACT_DURATION}, {MAX_IMPACT_DURATION}] s (one control period to "
            f"100 ms), got {duration}"
        )
    return duration


def tangential_velocity(velocity, normal: np.ndarray, what: str = "the tangential velocity") -> np.ndarray:
    """A tangential contact velocity (m/s) orthogonal to the unit ``normal``.

    One policy: a component along the normal larger than ORTHOGONALITY_TOLERANCE is rejected, with
    the offending component in the message; it is never silently projected away.
    """
    v_t = finite_vector(velocity, 3, what)
    if float(np.linalg.norm(v_t)) > MAX_CONTACT_SPEED:
        raise BadInputError(f"{what} must be at most {MAX_CONTACT_SPEED} m/s, got {np.linalg.norm(v_t):.3g} m/s")
    along = float(v_t @ normal)
    if abs(along) > ORTHOGONALITY_TOLERANCE:
        raise BadInputError(
            f"{what} must be orthogonal to the normal: its component along the normal is {along:.3g} m/s"
        )
    return v_t
