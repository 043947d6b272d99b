"""The one place that validates the physical inputs shared across the package.

Every caller that takes a surface normal, a restitution coefficient or a tangential velocity goes
through these functions, so each kind of input has one tolerance, one policy and one message.
Bad input raises :class:`BadInputError`; the command line turns it into one line on stderr and
exit code 2. Anything else that escapes is an internal error (exit code 1).
"""

from __future__ import annotations

import math
from pathlib import PurePath

import numpy as np

NORMAL_MIN_NORM = 1e-9
"""A normal shorter than this cannot be normalised."""

MAX_CONTACT_SPEED = 3.0
"""Largest contact speed (m/s) accepted anywhere: the Panda's end effector tops out near 2 m/s."""

ORTHOGONALITY_TOLERANCE = 1e-6
"""Largest |v_t . n| (m/s) accepted for a tangential velocity; larger is rejected, never projected."""


MAX_MESSAGE_CHARACTERS = 600
"""Longest message of a BadInputError: a message that quotes a hostile value (a huge list, a
long string) quotes its beginning only."""


class BadInputError(ValueError):
    """Input that the user can fix: a wrong value, shape, unit, file or request.

    The message is one line that names the offending input, at most ``MAX_MESSAGE_CHARACTERS``
    long (a longer one keeps its beginning and says it was cut).
    """

    def __init__(self, *args):
        if len(args) == 1 and isinstance(args[0], str) and len(args[0]) > MAX_MESSAGE_CHARACTERS:
            args = (args[0][: MAX_MESSAGE_CHARACTERS - 15] + " ... (cut)",)
        super().__init__(*args)


SHORT_VECTOR = 16
"""Entries up to which a vector is tested in plain floats (cheaper than a numpy call)."""


def all_finite(*vectors: np.ndarray) -> bool:
    """Whether every entry of the float ``vectors`` is finite: short vectors (a joint state, a
    normal) in plain floats, which is cheaper than a numpy call and cannot overflow, as a dot
    product of large finite entries would; longer ones with ``np.isfinite``."""
    return all(
        all(map(math.isfinite, v.tolist())) if v.size <= SHORT_VECTOR else bool(np.isfinite(v).all())
        for v in vectors
    )


def real_array(value, what: str, error: type[BadInputError] = BadInputError) -> np.ndarray:
    """``value`` as a float array (no copy when it is one), or ``error`` naming ``what``: a
    boolean is not a number (as in :func:`number_in_range`), a complex number is not a real one
    (numpy would drop its imaginary part with a warning), and neither is a text ("0.1")."""
    try:
        array = np.asarray(value)
        if _holds_boolean(value) or array.dtype.kind in "bcUSV":
            raise TypeError(array.dtype.kind)
        return array.astype(float, copy=False)
    except (TypeError, ValueError):
        raise error(f"{what} must hold real numbers, got {short_repr(value)}") from None


def short_repr(value) -> str:
    """``repr(value)`` cut to 60 characters (a message quotes the beginning of a long value)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def finite_vector(value, size: int | None, what: str) -> np.ndarray:
    """``value`` as a finite float vector of ``size`` entries (any size when None); a boolean is
    not a number (as in :func:`number_in_range`)."""
    if _holds_boolean(value):
        raise BadInputError(f"{what} must be a vector of numbers, got {value!r}")
    array = real_array(value, what)
    if array.ndim != 1 or (size is not None and array.shape[0] != size):
        expected = f"{size} numbers" if size is not None else "a flat list of numbers"
        raise BadInputError(f"{what} must be {expected}, got shape {array.shape}")
    if not all_finite(array):
        raise BadInputError(f"{what} must be finite, got {array.tolist()}")
    return array


def _holds_boolean(value) -> bool:
    """Whether ``value`` is a boolean or a list or tuple holding one (numpy would read it as 0 or 1)."""
    if isinstance(value, (list, tuple)):
        return any(isinstance(x, (bool, np.bool_)) for x in value)
    return isinstance(value, (bool, np.bool_)) or (isinstance(value, np.ndarray) and value.dtype == np.bool_)


def finite_array(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (a matrix; a vector is :func:`finite_vector`)."""
    array = real_array(value, what)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise BadInputError(f"{what} must be {shape} finite values, got {short_repr(value)}")
    return array


def vector_in_range(value, size: int, low: float, high: float, what: str, unit: str = "") -> np.ndarray:
    """``value`` as :func:`finite_vector` of ``size`` entries, each in [low, high] (the message
    names the entry, ``what[i]``)."""
    array = finite_vector(value, size, what)
    for i, x in enumerate(array.tolist()):
        number_in_range(x, low, high, f"{what}[{i}]", unit)
    return array


ROTATION_TOLERANCE = 1e-6
"""Largest entry of R^T R - I accepted for a rotation matrix given as numbers (a file's nine
numbers at about seven digits)."""


def rotation_matrix(value, what: str) -> np.ndarray:
    """``value`` as a rotation matrix: 3 x 3 finite numbers with R^T R = I (to
    ROTATION_TOLERANCE) and det R = +1 (not a reflection)."""
    R = finite_array(value, (3, 3), what)
    if np.abs(R.T @ R - np.eye(3)).max() > ROTATION_TOLERANCE or np.linalg.det(R) < 0.0:
        raise BadInputError(f"{what} must be a rotation matrix (R^T R = I, det R = 1), got {R.tolist()}")
    return R


def positive_vector(value, size: int, what: str, high: float | None = None) -> np.ndarray:
    """``value`` as :func:`finite_vector` of ``size`` entries, each > 0 (limits, bounds) and, when
    ``high`` is given, each in (0, high] (a stiffness, a threshold)."""
    array = finite_vector(value, size, what)
    if high is not None and not np.all((array > 0.0) & (array <= high)):
        raise BadInputError(f"{what} must lie in (0, {high:g}], got {array.tolist()}")
    if not np.all(array > 0.0):
        raise BadInputError(f"{what} must be > 0, got {array.tolist()}")
    return array


def unit_normal(normal, what: str = "the surface normal") -> np.ndarray:
    """The normalised 3-vector ``normal``; a non-finite or (near-)zero normal is bad input."""
    n = finite_vector(normal, 3, what)
    # |n| = s |n / s| with s = max |n_i|: the norm of n / s lies in [1, sqrt(3)], so neither it
    # nor the division overflows for any finite n (|n| itself may exceed the float range); in
    # plain floats, cheaper than numpy calls for three entries
    x, y, z = n.tolist()
    scale = max(abs(x), abs(y), abs(z))
    if scale > 0.0:
        x, y, z = x / scale, y / scale, z / scale
    norm = math.hypot(x, y, z)
    if scale * norm < NORMAL_MIN_NORM:
        raise BadInputError(f"{what} must be non-zero, got {n.tolist()}")
    return np.array((x / norm, y / norm, z / norm))


def unit_normals(normals, what: str = "the surface normals") -> np.ndarray:
    """A (3,) normal or (N, 3) normals, each normalised: ``unit_normal`` row by row, vectorised."""
    try:
        array = np.asarray(normals, dtype=float)
    except (TypeError, ValueError) as exc:
        raise BadInputError(f"{what} must be an array of numbers") from exc
    if array.ndim not in (1, 2) or array.shape[-1] != 3:
        raise BadInputError(f"{what} must be (3,) or (N, 3), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise BadInputError(f"{what} must be finite")
    # Scaled norms, |n| = s |n / s| with s = max |n_i|: no square of a large entry can overflow.
    scale = np.abs(array).max(axis=-1, keepdims=True)
    if np.any(scale == 0.0):
        raise BadInputError(f"{what} must be non-zero")
    scaled = array / scale
    norms = np.linalg.norm(scaled, axis=-1, keepdims=True)  # in [1, sqrt(3)]
    if np.any(scale < NORMAL_MIN_NORM / norms):
        raise BadInputError(f"{what} must be non-zero")
    return scaled / norms


def number_in_range(value, low: float, high: float, what: str, unit: str = "", low_open: bool = False) -> float:
    """``value`` as a finite float in [low, high] ((low, high] with ``low_open``); a boolean, a
    string or anything outside the range is bad input, and the message gives the range."""
    span = f"{'(' if low_open else '['}{low:g}, {high:g}]{' ' + unit if unit else ''}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise BadInputError(f"{what} must be a number in {span}, got {value!r}")
    number = float(value)
    inside = (low < number if low_open else low <= number) and number <= high
    if not (math.isfinite(number) and inside):
        raise BadInputError(f"{what} must lie in {span}, got {number}")
    return number


def whole_number(value, low: int, high: int | None, what: str) -> int:
    """``value`` as an int in [low, high] ([low, inf) when ``high`` is None); a boolean, a float
    or anything outside the range is bad input, and the message gives the range."""
    span = f"in [{low}, {high}]" if high is not None else f">= {low}"
    inside = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not (inside and low <= value and (high is None or value <= high)):
        raise BadInputError(f"{what} must be a whole number {span}, got {value!r}")
    return int(value)


MAX_TRIALS = 1000
"""Most trials one request simulates or fits unless its caller raises the limit (``max_trials``,
``--max-trials`` on the command line): the bound that keeps a typo in a list of speeds or repeats
from asking for hours of work."""


def trial_count(count: int, limit: int, what: str, how: str = "") -> int:
    """``count`` trials of ``what`` when within ``limit`` (a whole number >= 1); beyond it bad
    input that gives the count (and ``how`` it is made up) and how to raise the limit."""
    whole_number(limit, 1, None, "the trial limit --max-trials")
    if count > limit:
        raise BadInputError(
            f"{what} has {count:,} trials{f' ({how})' if how else ''}, more than the limit of {limit:,}: "
            f"ask for fewer, or raise the limit with --max-trials {count}"
        )
    return count


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless one: "1 posture", "3 speeds"."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def boolean(value, what: str) -> bool:
    """``value`` as a bool; only ``true``/``false`` are accepted (never 1, "yes" or a string)."""
    if not isinstance(value, (bool, np.bool_)):
        raise BadInputError(f"{what} must be true or false, got {value!r}")
    return bool(value)


def number(value, what: str) -> float:
    """A number of a parsed file (not a boolean, not a string) as a float; not checked for finiteness."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise BadInputError(f"{what} must be a number, got a {type(value).__name__}")
    return float(value)


def numbers(value, count: int, what: str) -> tuple[float, ...]:
    """A list of ``count`` numbers of a parsed file (each one :func:`number`)."""
    if not isinstance(value, list) or len(value) != count:
        raise BadInputError(f"{what} must be a list of {count} numbers")
    return tuple(number(x, f"{what}[{i}]") for i, x in enumerate(value))


def positive(value, what: str, unit: str = "") -> float:
    """A finite number > 0 (a spacing, a tolerance, a threshold) as a float."""
    value = number(value, what)
    if not (math.isfinite(value) and value > 0.0):
        raise BadInputError(f"{what} must be > 0{' ' + unit if unit else ''}, got {value}")
    return value


MAX_GAIN = 1e6
"""Largest task gain, weight or speed accepted: beyond it the task's rows outweigh the damping
task (weight 1e-4) by more than 1e10 and the QP's Hessian loses every other objective."""


def task_gain(value, what: str) -> float:
    """A task gain, weight or speed: a number in [0, MAX_GAIN]."""
    return number_in_range(value, 0.0, MAX_GAIN, what)


def non_empty_string(value, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise BadInputError(f"{what} must be a non-empty string, got a {type(value).__name__}")
    return value


def non_empty_list(value, what: str) -> list:
    if not isinstance(value, list) or not value:
        raise BadInputError(f"{what} must be a non-empty list")
    return value


def table(value, what: str) -> dict:
    """A table of keys and values of a parsed file (a dict)."""
    if not isinstance(value, dict):
        raise BadInputError(f"{what} must be a table of keys and values, got {type(value).__name__}")
    return value


def file_inside(value, what: str, directory: str) -> str:
    """A file name of a parsed file: a plain relative path that stays inside ``directory`` (no
    absolute path, no '..', no '~')."""
    name = non_empty_string(value, what)
    path = PurePath(name)
    if path.is_absolute() or ".." in path.parts or name.startswith("~"):
        raise BadInputError(f"{what} must name a file inside {directory}")
    return name


def vector_rows(value, rows: int, what: str) -> np.ndarray:
    """A (3,) vector or ``rows`` vectors (rows, 3) of finite numbers as (rows, 3) (one vector
    broadcast to every row, read-only)."""
    array = real_array(value, what)
    if array.shape not in ((3,), (rows, 3)):
        raise BadInputError(f"{what} must be (3,) or ({rows}, 3), got shape {array.shape}")
    if not all_finite(array.ravel()):
        raise BadInputError(f"{what} must be finite")
    return np.broadcast_to(array, (rows, 3))


def state_rows(value, size: int, what: str) -> np.ndarray:
    """A batch of states (N, size) of finite numbers."""
    array = real_array(value, what)
    if array.ndim != 2 or array.shape[1] != size:
        raise BadInputError(f"{what} must have shape (N, {size}), got {array.shape}")
    if not all_finite(array.ravel()):
        raise BadInputError(f"{what} contains a non-finite value")
    return array


def name_in(value, choices, what: str) -> str:
    """``value`` as one of the string ``choices``; the message lists them."""
    if not isinstance(value, str) or value not in choices:
        raise BadInputError(f"{what} = {value!r}; choose from {', '.join(choices)}")
    return value


def restitution(value, what: str = "the restitution") -> float:
    """The coefficient of restitution c_r, in [0, 1] (0: the contact sticks, 1: elastic)."""
    return number_in_range(value, 0.0, 1.0, what)


def approach_speed(value, what: str = "the approach speed") -> float:
    """An approach speed along -n in m/s, in (0, MAX_CONTACT_SPEED]."""
    return number_in_range(value, 0.0, MAX_CONTACT_SPEED, what, "m/s", low_open=True)


def tangential_speed(value, what: str = "the tangential speed") -> float:
    """A signed speed (m/s) along a tangential direction of the surface: its magnitude at most
    MAX_CONTACT_SPEED (its sign picks the direction; 0 is an approach along the normal)."""
    return number_in_range(value, -MAX_CONTACT_SPEED, MAX_CONTACT_SPEED, what, "m/s")


def repeated(values) -> list:
    """The values listed more than once in ``values``, sorted (each once)."""
    values = list(values)
    return sorted({v for v in values if values.count(v) > 1})


def distinct_names(names, what: str) -> None:
    """BadInputError when a name of ``names`` is listed more than once (each names one condition)."""
    twice = repeated(names)
    if twice:
        raise BadInputError(f"{what} repeat {', '.join(map(str, twice))}")


MIN_SIMULATED_SPEED = 1e-3
"""m/s: the slowest approach a simulated trial takes. A trial allows its approach a few times
gap / speed of simulated time (unbounded as the speed goes to 0), and a slower impact stays
below the joint-torque residual's detection threshold."""


def simulated_speed(value, what: str = "the approach speed") -> float:
    """An approach speed (m/s) that a simulated trial can reach the wall at: in
    [MIN_SIMULATED_SPEED, MAX_CONTACT_SPEED]."""
    return number_in_range(value, MIN_SIMULATED_SPEED, MAX_CONTACT_SPEED, what, "m/s")


MIN_IMPACT_DURATION, MAX_IMPACT_DURATION = 1e-3, 0.1
"""s: an impact lasts at least one 1 kHz control period and far less than 0.1 s (the paper's
impacts last about 15 ms, 25 ms at most)."""


def impact_duration(value, what: str = "the impact duration") -> float:
    """The impact duration delta_t (s) of the impulsive-torque bound: one control period to 100 ms."""
    return number_in_range(value, MIN_IMPACT_DURATION, MAX_IMPACT_DURATION, what, "s (one control period to 100 ms)")


def tangential_velocity(velocity, normal: np.ndarray, what: str = "the tangential velocity") -> np.ndarray:
    """A tangential contact velocity (m/s) orthogonal to the unit ``normal``.

    One policy: a component along the normal larger than ORTHOGONALITY_TOLERANCE is rejected, with
    the offending component in the message; it is never silently projected away.
    """
    v_t = finite_vector(velocity, 3, what)
    speed = math.hypot(*v_t.tolist())  # scaled: no overflow for any finite speed up to the float range
    if speed > MAX_CONTACT_SPEED:
        # beyond the float range the largest component is the number the user gave
        given = speed if math.isfinite(speed) else max(map(abs, v_t.tolist()))
        raise BadInputError(f"{what} must be at most {MAX_CONTACT_SPEED} m/s, got {given:.3g} m/s")
    along = float(v_t @ normal)
    if abs(along) > ORTHOGONALITY_TOLERANCE:
        raise BadInputError(
            f"{what} must be orthogonal to the normal: its component along the normal is {along:.3g} m/s"
        )
    return v_t


def rigid_body_moments(moments, slack: float) -> bool:
    """Whether principal moments A <= B <= C (kg m^2) are a rigid body's within ``slack``: each
    >= 0 and C at most A + B (the triangle inequality)."""
    return bool(moments[0] >= -slack and moments[2] <= moments[0] + moments[1] + slack)
