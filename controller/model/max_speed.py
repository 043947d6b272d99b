"""Closed-form highest feasible contact speed of a posture (docs/max-speed.md).

The approach motion is dq- = v d with d = J6+ [-n; 0]: the contact frame translates along -n
without rotating (J6 the 6x7 world-aligned frame Jacobian, + the pseudo-inverse). Then
v- = J dq- = -v n, and every quantity below is linear in the speed v:

  (a) velocity_pre:      |dq-_i|               = v |d_i|                 <= dq_max_i
  (b) velocity_post:     |(I + A) dq-|_i        = v |((I + A) d)_i|       <= dq_max_i
  (c) impulsive_torque:  |J^T iota|_i / delta_t = v |(J^T G (-n))_i| / delta_t <= tau_max_i

with A = K G J the jump matrix of the chosen model. The maximum feasible speed is the smallest
ratio limit_i / slope_i over joints and criteria; the arg-min says what binds.

:func:`closed_form_max_speeds` evaluates the same for N postures at once on the batched terms and
predictor of ``controller.model.jump`` (stacked pseudo-inverses, Cholesky solves with M).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .batch import BatchTerms
from .jump import JumpModel, predict_from_terms
from .robot import ModelTerms, PandaModel

CRITERIA = ("velocity_pre", "velocity_post", "impulsive_torque")
DEFAULT_IMPACT_DURATION = 0.015


@dataclass(frozen=True)
class MaxSpeed:
    speed: float
    criterion: str
    joint: int  # 1-based joint index


def approach_direction(terms: ModelTerms, normal: np.ndarray) -> np.ndarray:
    """d = J6+ [-n; 0]: joint velocity per unit approach speed along -n without rotation."""
    return np.linalg.pinv(terms.J6) @ np.concatenate([-np.asarray(normal, float), np.zeros(3)])


def criterion_slopes(
    robot: PandaModel,
    terms: ModelTerms,
    normal: np.ndarray,
    model: JumpModel,
    restitution: float = 0.0,
    impact_duration: float = DEFAULT_IMPACT_DURATION,
) -> dict[str, np.ndarray]:
    """Per-joint ratio to the limit at unit approach speed, for each criterion (a), (b), (c)."""
    normal = np.asarray(normal, float)
    d = approach_direction(terms, normal)
    maps = model.maps(terms, normal, restitution)
    impulse = maps.G @ (terms.J @ d)
    post = d + maps.K @ impulse
    return {
        "velocity_pre": np.abs(d) / robot.dq_max,
        "velocity_post": np.abs(post) / robot.dq_max,
        "impulsive_torque": np.abs(terms.J.T @ impulse) / impact_duration / robot.tau_max,
    }


def closed_form_max_speed(
    robot: PandaModel,
    terms: ModelTerms,
    normal: np.ndarray,
    model: JumpModel,
    restitution: float = 0.0,
    impact_duration: float = DEFAULT_IMPACT_DURATION,
) -> MaxSpeed:
    """Highest approach speed v for which (a), (b) and (c) all hold, and what binds it."""
    slopes = criterion_slopes(robot, terms, normal, model, restitution, impact_duration)
    best = MaxSpeed(np.inf, "", 0)
    for criterion in CRITERIA:
        s = slopes[criterion]
        j = int(np.argmax(s))
        if s[j] > 0 and 1.0 / s[j] < best.speed:
            best = MaxSpeed(float(1.0 / s[j]), criterion, j + 1)
    return best


@dataclass(frozen=True)
class MaxSpeeds:
    """:class:`MaxSpeed` of N postures: speed (N,), index into CRITERIA (N,; -1 when nothing
    binds) and 1-based joint (N,; 0 when nothing binds)."""

    speed: np.ndarray
    criterion: np.ndarray
    joint: np.ndarray


def approach_directions(terms: BatchTerms, normals: np.ndarray) -> np.ndarray:
    """:func:`approach_direction` of N postures: d = J6+ [-n; 0] (N, nv), J6 = [J; joint axes]."""
    normals = np.broadcast_to(np.asarray(normals, float), terms.J.shape[:1] + (3,))
    J6 = np.concatenate([terms.J, np.swapaxes(terms.joint_axes, 1, 2)], axis=1)
    target = np.concatenate([-normals, np.zeros_like(normals)], axis=1)
    return (np.linalg.pinv(J6) @ target[..., None])[..., 0]


def closed_form_max_speeds(
    robot: PandaModel,
    terms: BatchTerms,
    normals: np.ndarray,
    model: str,
    restitution: float = 0.0,
    impact_duration: float = DEFAULT_IMPACT_DURATION,
    directions: np.ndarray | None = None,
) -> MaxSpeeds:
    """:func:`closed_form_max_speed` of N postures (``terms``) and unit ``normals`` (N, 3);
    ``directions``: their :func:`approach_directions`, when already known (they depend on
    neither the model, nor the restitution, nor the impact duration)."""
    normals = np.broadcast_to(np.asarray(normals, float), terms.J.shape[:1] + (3,))
    d = approach_directions(terms, normals) if directions is None else directions
    v = (terms.J @ d[..., None])[..., 0]
    jump, impulse = predict_from_terms(terms, normals, v, restitution, model)
    Jt_impulse = (np.swapaxes(terms.J, 1, 2) @ impulse[..., None])[..., 0]
    slopes = np.stack(
        [
            np.abs(d) / robot.dq_max,
            np.abs(d + jump) / robot.dq_max,
            np.abs(Jt_impulse) / impact_duration / robot.tau_max,
        ],
        axis=1,
    )  # (N, criterion, joint), in the order of CRITERIA
    joint = np.argmax(slopes, axis=2)
    rate = np.take_along_axis(slopes, joint[..., None], axis=2)[..., 0]
    with np.errstate(divide="ignore"):
        speeds = np.where(rate > 0.0, 1.0 / rate, np.inf)
    criterion = np.argmin(speeds, axis=1)
    rows = np.arange(len(criterion))
    speed = speeds[rows, criterion]
    binds = np.isfinite(speed)
    return MaxSpeeds(
        speed,
        np.where(binds, criterion, -1),
        np.where(binds, joint[rows, criterion] + 1, 0),
    )
