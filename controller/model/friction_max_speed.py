"""An arm's highest feasible normal contact speed under the robust friction rows
(docs/frictional-impacts.md, docs/max-speed.md).

The approach slides at a tangential velocity v_t besides its normal speed v: dq-(v) = v d + d_t,
d = J6+ [-n; 0], d_t = J6+ [v_t; 0] (J6 the world-aligned frame Jacobian), and the post-impact
velocity and impulsive torque hold for the frictionless impulse and for every edge of the robust
friction rows (``friction_pyramid``): |a_i + v b_i| <= L_i per joint and block, an interval
[0, v_max], whose smallest end is the answer.

The frictionless criteria and their closed form are ``max_speed``'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .friction_pyramid import FrictionRows, edge_directions, edge_matrices, response_maps
from .frictional_impact import frictional_impulse
from .jump import jump_model
from .max_speed import Bound, MaxSpeed, Setting
from .robot import RobotModel
from .validation import BadInputError


@dataclass(frozen=True)
class FrictionalMaxSpeed:
    """:func:`frictional_max_speed`'s answer: the highest normal speed and what binds it
    (``MaxSpeed``; its bounds the smallest over the blocks), the binding block ("frictionless" or
    "edge i"), and the contact's ``mode`` per ``frictional_impulse`` at that speed with the
    stick coefficient ``mu_bar`` ("" and nan when the speed is 0 or unbounded)."""

    max_speed: MaxSpeed
    block: str
    mode: str
    mu_bar: float


def affine_bound(robot: RobotModel, start: np.ndarray, slope: np.ndarray, limit: np.ndarray) -> Bound:
    """The largest v >= 0 with |start + v slope| <= limit on every joint (0 when v = 0 already
    violates it), at the joint that gives it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        speeds = np.where(slope > 0.0, (limit - start) / slope, np.where(slope < 0.0, (limit + start) / -slope, np.inf))
    speeds = np.where(np.abs(start) > limit, 0.0, speeds)
    i = int(np.argmin(speeds))
    return Bound(float(speeds[i]), robot.description.joints[i], i + 1) if math.isfinite(speeds[i]) else Bound(math.inf)


def frictional_max_speed(
    robot: RobotModel, terms, normal, tangential: np.ndarray, setting: Setting, rows: FrictionRows
) -> FrictionalMaxSpeed:
    """The highest normal contact speed of an arm's posture (``terms``) sliding at the tangential
    velocity ``tangential`` (orthogonal to the unit ``normal``) under the robust friction rows
    ``rows`` of the predictor ``setting.method`` (module docstring), and the mode of the
    frictional impact (``frictional_impulse``, mu = rows.friction) at that speed. The preview's
    edges (mode "slip") are those of the contact velocity at the answer: first of v_t alone, then,
    when the slip is not certain at the speed found, the whole cone's (their speed is then the answer)."""
    if robot.description.held_contacts:
        raise BadInputError("the frictional maximum speed is an arm's; a robot on held contacts has none")
    normal = np.asarray(normal, dtype=float)
    W = response_maps(jump_model(setting.method), terms, normal, setting.restitution)[1]
    directions = edge_directions(rows, normal, tangential, W, setting.restitution)
    best, block = _rows_max_speed(robot, terms, normal, tangential, setting, directions)
    if rows.mode == "slip" and 0.0 < best.speed < math.inf:
        at_speed = edge_directions(rows, normal, tangential - best.speed * normal, W, setting.restitution)
        if not np.array_equal(at_speed, directions):
            best, block = _rows_max_speed(robot, terms, normal, tangential, setting, at_speed)
    if not 0.0 < best.speed < math.inf:
        return FrictionalMaxSpeed(best, block, "", math.nan)
    impact = frictional_impulse(W, normal, tangential - best.speed * normal, rows.friction, setting.restitution)
    return FrictionalMaxSpeed(best, block, impact.mode, impact.mu_bar)


def _rows_max_speed(robot: RobotModel, terms, normal, tangential, setting: Setting, directions) -> tuple[MaxSpeed, str]:
    """The closed form under the frictionless and the ``directions`` edge blocks, and its binding block."""
    pinv6, model = np.linalg.pinv(terms.J6), jump_model(setting.method)
    d, d_t = pinv6 @ np.concatenate([-normal, np.zeros(3)]), pinv6 @ np.concatenate([tangential, np.zeros(3)])
    own, edges = model.matrices(terms, normal, setting.restitution), edge_matrices(model, terms, normal, directions, setting.restitution)
    blocks = {"frictionless": (own.jump_matrix, own.torque_matrix)}
    blocks |= {f"edge {i}": (A, P) for i, (A, P) in enumerate(zip(edges.jump, edges.torque))}
    torque_limit = robot.tau_max * setting.duration(robot.description)
    bounds = {"velocity_pre": affine_bound(robot, d_t, d, robot.dq_max)}
    block_of = {"velocity_pre": ""}
    for name, (A, P) in blocks.items():
        for criterion, start, slope, limit in (
            ("velocity_post", d_t + A @ d_t, d + A @ d, robot.dq_max),
            ("impulsive_torque", P @ d_t, P @ d, torque_limit),
        ):
            bound = affine_bound(robot, start, slope, limit)
            if criterion not in bounds or bound.speed < bounds[criterion].speed:
                bounds[criterion], block_of[criterion] = bound, name
    criterion = min(bounds, key=lambda c: bounds[c].speed)
    best = bounds[criterion]
    return MaxSpeed(best.speed, "" if best.speed == math.inf else criterion, best.where, best.joint, bounds), block_of[criterion]
