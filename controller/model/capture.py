"""Post-impact centre-of-mass velocity and the zero-step capture region (docs/floating-base.md).

Zero-step capture region. With the linear inverted pendulum of the CoM at height h above the
ground, omega = sqrt(g / h), the robot can stop without a step when the instantaneous capture
point xi = c + dc / omega (horizontal parts) lies in the support polygon S. With S written as
half-planes nu_k . x <= nu_k . a_k (outward unit normals nu_k of its edges, a_k a point of
edge k), the CoM velocities that keep xi inside S are the polygon

    (nu_k / omega) . dc <= nu_k . (a_k - c)        for every edge k,

a set of linear inequalities A dc <= b in the CoM velocity: the capture region of the stance.

Post-impact CoM velocity. A hand impulse iota (from one predictor's impulse map, eqs. 6 or 12)
acting on the robot with both feet held changes the generalized velocity by P J^T iota
(``jump``), so the CoM velocity jumps by C iota with C = Jcom P J^T (3x3); this equals
(iota + the feet's impulsive forces) / m. As every predictor's impulse is linear in the contact
velocity v-, dc+ = dc- + C iota(v-) is linear in v-, and the highest capturable contact speed
along an approach direction has a closed form (:func:`max_capturable_speed`).

Non-coplanar soles (a foot on a step; docs/floating-base.md, "Non-coplanar soles"). With the
contact force of every sole corner p_i directed at the CoM, f_i = l_i (c - p_i), l_i >= 0 (inside
a horizontal sole's friction cone while |c_xy - p_i,xy| <= mu (c_z - p_i,z)), the moment about c
vanishes and, at constant CoM height, c''_xy = omega^2 (c_xy - z) with omega^2 = g / c_z and

    z = sum_i mu_i (c_xy + k_i (p_i,xy - c_xy)),   k_i = c_z / (c_z - p_i,z),   mu_i >= 0, sum mu_i = 1:

the floor-plane ZMP ranges over the convex hull of the corners projected from the CoM onto the
floor (:func:`floor_support_polygon`). Coplanar soles on the floor have k_i = 1: the polygon is
the soles' hull and the region the one above. A sole's surface height is read from the posture
(its corners' mean height; the floor's, 0, within :data:`FLOOR_TOLERANCE`).

Simplifications: GM and CRB impulses are frictionless (along the normal, eq. 12), the classical
one sticking (eq. 6); the feet are held during the impulse (their impulsive wrenches are not
checked against friction or the soles); the capture point is the linear pendulum's (constant CoM
height, no angular momentum); with non-coplanar soles, the contact forces point at the CoM (an
inner part of the contact wrench cone: no internal forces between the soles) and the projected
polygon is taken at the CoM of the instant (as the CoM moves by dc, a raised sole's projected
corners move by (1 - k_i) dc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .jump import constrained_inverse_inertia, predict
from .model_terms import ModelTerms
from .humanoid_stance import convex_hull, edge_margins, edge_normals
from .robot import RobotModel
from .validation import BadInputError

GRAVITY = 9.81
FLOOR_TOLERANCE = 0.01
"""m: a sole whose corners lie within this of the floor (z = 0) on average stands on the floor."""


@dataclass(frozen=True)
class CaptureRegion:
    """A dc_xy <= b: the horizontal CoM velocities from which the robot stops without a step."""

    A: np.ndarray  # (k, 2)
    b: np.ndarray  # (k,)
    omega: float  # sqrt(g / h), 1/s

    def margins(self, com_velocity) -> np.ndarray:
        """b - A dc_xy (m): the capture point's distance inside each edge of the support polygon."""
        return self.b - self.A @ np.asarray(com_velocity, dtype=float)[:2]

    def contains(self, com_velocity) -> bool:
        return bool(np.all(self.margins(com_velocity) >= 0.0))


def capture_region(polygon: np.ndarray, com: np.ndarray, ground_height: float = 0.0) -> CaptureRegion:
    """The capture region (module docstring) of the counter-clockwise convex support ``polygon``
    (k x 2) for the CoM at ``com`` (3)."""
    polygon = np.asarray(polygon, dtype=float)
    com = np.asarray(com, dtype=float)
    height = com[2] - ground_height
    if polygon.ndim != 2 or polygon.shape[0] < 3 or polygon.shape[1] != 2:
        raise BadInputError("the support polygon needs at least three (x, y) vertices")
    if not height > 0.0:
        raise BadInputError(f"the centre of mass must be above the ground, got height {height}")
    omega = math.sqrt(GRAVITY / height)
    return CaptureRegion(edge_normals(polygon) / omega, edge_margins(polygon, com), omega)


def support_heights(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """(held contacts,): the height of each sole's support surface in the posture q, its corners'
    mean height, 0 (the floor) within :data:`FLOOR_TOLERANCE` of it."""
    corners = robot.sole_corners(q)
    sizes = [len(c.sole) for c in robot.description.held_contacts]
    heights = np.array([part[:, 2].mean() for part in np.split(corners, np.cumsum(sizes)[:-1])])
    heights[np.abs(heights) < FLOOR_TOLERANCE] = 0.0
    return heights


def floor_support_polygon(robot: RobotModel, q: np.ndarray, com: np.ndarray) -> np.ndarray:
    """The counter-clockwise convex hull (k x 2) of every sole corner p projected from the CoM c
    onto the floor, p_xy + (k - 1)(p_xy - c_xy) with k = c_z / (c_z - h) for the height h of the
    corner's support surface (module docstring): the soles' hull when they all stand on the
    floor (k = 1)."""
    corners = robot.sole_corners(q)[:, :2]
    com = np.asarray(com, dtype=float)
    heights = np.repeat(support_heights(robot, q), [len(c.sole) for c in robot.description.held_contacts])
    if not com[2] > heights.max():
        raise BadInputError(f"the centre of mass ({com[2]:.3f} m high) must be above every sole")
    scale = com[2] / (com[2] - heights) - 1.0
    return convex_hull(corners + scale[:, None] * (corners - com[:2]))


def support_capture_region(robot: RobotModel, q: np.ndarray, com: np.ndarray) -> CaptureRegion:
    """The zero-step capture region of the soles of the posture q for the CoM at ``com``: the
    capture point on the floor inside :func:`floor_support_polygon` (module docstring)."""
    return capture_region(floor_support_polygon(robot, q, com), com)


def com_jump_map(terms: ModelTerms) -> np.ndarray:
    """C = Jcom P J^T (3x3): the CoM velocity jump per unit hand impulse, both feet held."""
    return terms.Jcom @ constrained_inverse_inertia(terms) @ terms.J.T


def post_impact_com_velocity(terms: ModelTerms, method: str, normal, v_minus, com_velocity, c_r: float = 0.0):
    """dc+ = dc- + C iota, iota the impulse ``method`` predicts for the contact velocity v-."""
    impulse = predict(terms, method, normal, v_minus, c_r).impulse
    return np.asarray(com_velocity, dtype=float) + com_jump_map(terms) @ impulse


def row_steps(offset: np.ndarray, slope: np.ndarray) -> np.ndarray:
    """Per row of offset + s slope <= 0, the largest s >= 0 that keeps it: -offset / slope where the
    row rises (slope > 0), inf where it does not, 0 where it already fails (offset > 0)."""
    offset, slope = np.asarray(offset, dtype=float), np.asarray(slope, dtype=float)
    steps = np.full(offset.shape, math.inf)
    rising = slope > 0.0
    with np.errstate(over="ignore"):  # a vanishing slope allows an unbounded step: inf is the answer
        steps[rising] = np.maximum(-offset[rising], 0.0) / slope[rising]
    steps[offset > 0.0] = 0.0
    return steps


def capturable_speeds(
    terms: ModelTerms, region: CaptureRegion, method: str, normal, direction, c_r: float = 0.0
) -> np.ndarray:
    """Per edge k of the region, the largest s >= 0 with row k of A dc+ <= b for the contact
    velocity v- = s ``direction``, the pre-impact CoM velocity taken as zero (the hand moves, the
    body stands): b_k / (A_k C iota_1) where the unit-speed jump pushes outwards, inf elsewhere,
    0 on a row the standing robot already violates."""
    unit_jump = post_impact_com_velocity(terms, method, normal, direction, np.zeros(3), c_r)
    return row_steps(-region.margins(np.zeros(2)), region.A @ unit_jump[:2])


def max_capturable_speed(
    terms: ModelTerms, region: CaptureRegion, method: str, normal, direction, c_r: float = 0.0
) -> float:
    """The largest s >= 0 with dc+ inside the region for the contact velocity v- = s ``direction``
    (the smallest of :func:`capturable_speeds`; inf when no edge binds, 0 when the standing robot
    is already outside)."""
    return float(np.min(capturable_speeds(terms, region, method, normal, direction, c_r)))
