"""The highest feasible normal contact speed under the robust friction rows, for an arm and for a
robot standing on held contacts (docs/frictional-impacts.md, docs/max-speed.md).

The approach slides at a tangential velocity v_t besides its normal speed v: dq-(v) = v d + d_t,
the joint velocity moving the contact at -n and at v_t (``max_speed.contact_motion``: d =
J6+ [-n; 0], d_t = J6+ [v_t; 0] for an arm, J_arm+ on the contact's joints with held contacts).
Every vertex of the friction cone's section that the impulse may take, the frictionless impulse
and each edge of the robust friction rows (``friction_pyramid``: iota_i = G_i v-, the pyramid
circumscribing the cone, scaled by the normal impulse), is a block of criteria affine in v, each an
interval [0, v_max]; the smallest end over the blocks is the answer, and its block binds:

- an arm: the post-impact velocity and the impulsive torque |a_i + v b_i| <= L_i per joint and
  block (and |dq-| <= dq_max);
- on held contacts: the frictionless closed form's criteria (``max_speed.CRITERIA_WITH_HELD_CONTACTS``:
  joint velocity, foot slip, foot lift, capture) on each vertex's impulse, its jump (the predictor's
  held-contact K iota_i) and the held contacts' impulsive wrenches (``jump.held_impulse``).

With the one-step preview's rows (mode "slip") the edges depend on v: the sector's while the slip
of v_t - v n is certain, v <= v_c (:func:`_certain_slip_speed`), the 3-edge pyramid's
above. The answer is the highest speed up to which the rows, as the QP builds them at each speed,
hold: v_s, the sector's blocks' answer, when v_s <= v_c; else v_p, the pyramid's, when v_p > v_c;
else v_c itself (criterion ``certain_slip``): the sector's rows hold up to it, no row at its limit,
and the pyramid's fail at every faster speed.

The frictionless criteria and their closed form are ``max_speed``'s; the rows of the QP that
these bound are ``constraints.post_impact_velocity``, ``constraints.capture_constraint`` and
``constraints.foot_wrench`` (their edge classes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .friction_pyramid import (
    SLIP_EDGES, Edges, FrictionRows, edge_directions, edge_impulse_maps, edge_matrices, held_response_maps,
    pyramid_directions, response_maps, slip_edges_into,
)
from .frictional_impact import frictional_impulse
from .jump import jump_model
from .max_speed import (
    CRITERIA_WITH_HELD_CONTACTS, Bound, ImpactPart, MaxSpeed, Setting, UnitImpact, affine_bound, approach_direction,
    contact_motion,
)
from .robot import RobotModel


CERTAIN_SLIP = "certain_slip"
"""The criterion of an answer at v_c, the highest speed of the preview's certain slip (module docstring)."""


@dataclass(frozen=True)
class FrictionalMaxSpeed:
    """:func:`frictional_max_speed`'s answer: the highest normal speed and what binds it
    (``MaxSpeed``; its bounds the smallest over the blocks of the rows at that speed), the binding
    block ("frictionless" or "edge i"; at v_c, criterion :data:`CERTAIN_SLIP`, the pyramid's block
    that fails above it), and the contact's ``mode`` per ``frictional_impulse`` at that speed with
    the stick coefficient ``mu_bar`` ("" and nan when the speed is 0 or unbounded)."""

    max_speed: MaxSpeed
    block: str
    mode: str
    mu_bar: float


def frictional_max_speed(
    robot: RobotModel, terms, normal, tangential: np.ndarray, setting: Setting, rows: FrictionRows
) -> FrictionalMaxSpeed:
    """The highest normal contact speed of a posture (``terms``) sliding at the tangential
    velocity ``tangential`` (orthogonal to the unit ``normal``) under the robust friction rows
    ``rows`` of the predictor ``setting.method`` (module docstring: an arm's joint criteria, or the
    criteria of a robot on held contacts, per vertex), and the mode of the frictional impact
    (``frictional_impulse``, mu = rows.friction, the predictor's W) at that speed. The preview's
    edges (mode "slip") are those the QP takes at each speed: the sector's up to v_c, the 3-edge
    pyramid's above (module docstring)."""
    normal = np.asarray(normal, dtype=float)
    held = bool(robot.description.held_contacts)
    maps = held_response_maps if held else response_maps
    W = maps(jump_model(setting.method), terms, normal, setting.restitution)[1]
    blocks = _held_blocks_max_speed if held else _rows_max_speed
    mu, c_r = rows.friction, setting.restitution
    best, block = blocks(robot, terms, normal, tangential, setting, edge_directions(rows, normal, tangential, W, c_r))
    if rows.mode == "slip" and rows.count and 0.0 < best.speed < math.inf and (
        _slip_is_certain(mu, normal, tangential, W, c_r)
        and not _slip_is_certain(mu, normal, tangential - best.speed * normal, W, c_r)
    ):  # the sector's rows at v = 0 answered a speed where the QP takes the pyramid's
        switch = _certain_slip_speed(mu, normal, tangential, W, c_r, best.speed)
        sector = best
        best, block = blocks(robot, terms, normal, tangential, setting, pyramid_directions(normal, mu, SLIP_EDGES))
        if best.speed <= switch:
            best = MaxSpeed(switch, CERTAIN_SLIP, "", 0, sector.bounds | {CERTAIN_SLIP: Bound(switch)})
    if not 0.0 < best.speed < math.inf:
        return FrictionalMaxSpeed(best, block, "", math.nan)
    impact = frictional_impulse(W, normal, tangential - best.speed * normal, mu, c_r)
    return FrictionalMaxSpeed(best, block, impact.mode, impact.mu_bar)


def _slip_is_certain(friction: float, normal: np.ndarray, velocity: np.ndarray, W: np.ndarray, restitution: float) -> bool:
    """Whether the preview's slip at the contact velocity ``velocity`` is certain with the friction
    mu, the inverse inertia ``W`` and the restitution c_r: its edges are the sector's, not the
    3-edge pyramid's that ``friction_pyramid.slip_edges_into`` leaves when it is not."""
    uncertain = pyramid_directions(normal, friction, SLIP_EDGES)
    directions = uncertain.copy()
    slip_edges_into(np.asarray(velocity, dtype=float), np.asarray(W, dtype=float), normal, float(friction),
                    float(restitution), directions)
    return not np.array_equal(directions, uncertain)


def _certain_slip_speed(friction: float, normal: np.ndarray, tangential: np.ndarray, W: np.ndarray, restitution: float,
                        uncertain_speed: float) -> float:
    """v_c: the highest normal speed v at which the preview's slip at the contact velocity v_t - v n
    (``tangential`` v_t) is certain (:func:`_slip_is_certain`), given that it is at v = 0 and is
    not at ``uncertain_speed``. Of the preview's test only the bound on the tangential drift D
    depends on v, in proportion to p_max and so to |u_n| = v (``friction_pyramid``'s docstring):
    the certain speeds are the interval [0, v_c], and v_c is found by bisection on the test
    itself, to the last bit."""
    low, high = 0.0, float(uncertain_speed)
    while low < (middle := 0.5 * (low + high)) < high:
        if _slip_is_certain(friction, normal, tangential - middle * normal, W, restitution):
            low = middle
        else:
            high = middle
    return low


def smallest_over_blocks(blocks: dict[str, dict[str, Bound]]) -> tuple[MaxSpeed, str]:
    """Per criterion the smallest bound over the blocks (name -> criterion -> Bound), the
    criterion that gives the smallest of all (ties: the first criterion, then the first block) and
    its block ("" when nothing binds)."""
    bounds, block_of = {}, {}
    for name, block in blocks.items():
        for criterion, bound in block.items():
            if criterion not in bounds or bound.speed < bounds[criterion].speed:
                bounds[criterion], block_of[criterion] = bound, name
    criterion = min(bounds, key=lambda c: bounds[c].speed)
    best = bounds[criterion]
    if not math.isfinite(best.speed):
        return MaxSpeed(math.inf, "", "", 0, bounds), ""
    return MaxSpeed(best.speed, criterion, best.where, best.joint, bounds), block_of[criterion]


def _rows_max_speed(robot: RobotModel, terms, normal, tangential, setting: Setting, directions) -> tuple[MaxSpeed, str]:
    """An arm's closed form under the frictionless and the ``directions`` edge blocks, and its binding block."""
    model = jump_model(setting.method)
    d, d_t = contact_motion(robot, terms, -normal), contact_motion(robot, terms, tangential)
    own, edges = model.matrices(terms, normal, setting.restitution), edge_matrices(model, terms, normal, directions, setting.restitution)
    maps = {"frictionless": (own.jump_matrix, own.torque_matrix)}
    maps |= {f"edge {i}": (A, P) for i, (A, P) in enumerate(zip(edges.jump, edges.torque))}
    torque_limit = robot.tau_max * setting.duration(robot.description)
    blocks = {"": {"velocity_pre": affine_bound(robot, d_t, d, robot.dq_max)}}
    for name, (A, P) in maps.items():
        blocks[name] = {
            "velocity_post": affine_bound(robot, d_t + A @ d_t, d + A @ d, robot.dq_max),
            "impulsive_torque": affine_bound(robot, P @ d_t, P @ d, torque_limit),
        }
    return smallest_over_blocks(blocks)


def _held_blocks_max_speed(robot: RobotModel, terms, normal, tangential, setting: Setting, directions) -> tuple[MaxSpeed, str]:
    """On held contacts: the frictionless closed form's criteria on every vertex (module
    docstring), the predictor's own impulse map G and each edge's G_i of ``directions``, each
    vertex's impulse G (v J d + J d_t) affine in v, and the binding block."""
    model, c_r = jump_model(setting.method), setting.restitution
    d, d_t = approach_direction(robot, terms, normal), contact_motion(robot, terms, tangential)
    sliding = bool(np.any(tangential != 0.0))

    def part(G: np.ndarray, direction: np.ndarray) -> ImpactPart:
        """The joint velocity ``direction``, its impulse G J direction, the predictor's jump of that
        impulse and the held contacts' impulsive wrenches."""
        jump = model.predict(terms, normal, None, c_r, impulse=G @ (terms.J @ direction))
        return ImpactPart(direction, jump.dq_jump, jump.impulse, jump.held_impulse)

    W = held_response_maps(model, terms, normal, c_r)[1]
    impulse_maps = {"frictionless": model.maps(terms, normal, c_r).G}
    impulse_maps |= {f"edge {i}": G for i, G in enumerate(edge_impulse_maps(W, Edges(directions, normal, c_r)))}
    blocks = {}
    for name, G in impulse_maps.items():
        unit = UnitImpact(robot, terms, normal, setting, *part(G, d), part(G, d_t) if sliding else None)
        blocks[name] = {criterion: bound(unit) for criterion, bound in CRITERIA_WITH_HELD_CONTACTS.items()}
    return smallest_over_blocks(blocks)
