"""Closed-form highest feasible contact speed of a standing G1 stance (docs/floating-base.md).

The hand approaches the wall along -n at speed s with the body at rest: the right-arm joints
move at dq- = s d, d_arm = J_arm^+ (-n) (the simulated trial's command), every other velocity is
zero. Every predicted quantity of ``floating_base`` is linear in the contact velocity v- = J d s
(eqs. 6 and 12), so each criterion below is an inequality in s whose feasible set is an interval
[0, s_max]; the highest feasible speed is the smallest s_max and the criterion giving it binds.

(a) ``joint_velocity``: |dq-_i| = s |d_i| and |dq+_i| = s |(d + dv_1)_i| stay below dq_max_i for
    the joints (dv_1 the predicted jump at unit speed).
(b) the feet, both held during the impulse (``floating_base``), at the peak of the hand's force:
    the hand's force peaks at iota / T, T the contact's equivalent duration (its impulse over its
    peak force), and the ground's wrench on foot k is then F_k(s) / T with F_k(s) = T w_k +
    s lambda_k, w_k the standing wrench (the least-norm foot wrenches carrying the robot's weight)
    and lambda_k the predicted impulsive wrench at unit speed (world axes, about the foot frame).
    The criteria are homogeneous in F_k, so they are checked on F_k. Assumed plainly: the feet's
    impulsive wrenches peak with the hand's force, in the feet-held model's proportions, and the
    feet are flat.
    ``foot_slip``: |F_xy| <= mu F_z (the friction cone of the summed impulse; a quadratic in s;
    mu the held contact's ``friction`` unless the setting gives one for every foot).
    ``foot_lift``: the centre of pressure of F, about the sole (the held contact's ``depth``
    below the frame), stays inside the convex hull of the sole's corners (the held contact's
    ``sole``): nu_e . (-tau_y, tau_x) <= (nu_e . a_e) f_z for each edge e (outward normal nu_e,
    corner a_e); together these also give f_z >= 0.
(c) ``capture``: the post-impact CoM velocity stays in the zero-step capture region
    (``capture.capturable_speeds``, the smallest over the edges).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .capture import capturable_speeds, capture_region, row_steps
from .floating_base import FloatingBaseModel, FloatingBaseTerms, predict
from .humanoid_stance import convex_hull, edge_margins, edge_normals, support_polygon
from .validation import BadInputError

CRITERIA = ("joint_velocity", "foot_slip", "foot_lift", "capture")
IMPACT_DURATION = 0.0034  # s: T, the wall contact's equivalent duration (impulse / peak force; the simulated wall's)
ARM_JOINTS = tuple(f"right_{j}_joint" for j in (
    "shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw"))
FEET = ("left", "right")
"""How a foot bound names the G1's held contacts (``Bound.where``), in the description's order."""


@dataclass(frozen=True)
class Setting:
    """What the closed form assumes: predictor, restitution, friction mu of every foot (None: each
    held contact's own ``friction``, the description's) and contact duration T (s)."""

    method: str = "crb"
    restitution: float = 0.0
    friction: float | None = None
    impact_duration: float = IMPACT_DURATION


@dataclass(frozen=True)
class Bound:
    """One criterion's highest feasible speed (m/s, inf when it never binds) and where it binds:
    a joint name, a foot (left, right) or an edge of the support polygon ("edge k")."""

    speed: float
    where: str


@dataclass(frozen=True)
class HumanoidMaxSpeed:
    """The highest feasible contact speed, the criterion that binds it, and every criterion's bound."""

    speed: float
    criterion: str
    where: str
    bounds: dict  # criterion -> Bound

    def to_json(self) -> dict:
        def finite(x):
            return x if math.isfinite(x) else None

        return {
            "speed": finite(self.speed), "criterion": self.criterion, "where": self.where,
            "bounds": {c: {"speed": finite(b.speed), "where": b.where} for c, b in self.bounds.items()},
        }


def approach_direction(robot: FloatingBaseModel, terms: FloatingBaseTerms, normal) -> np.ndarray:
    """d (nv): the velocity per unit approach speed, right-arm joints J_arm^+ (-n), the rest zero."""
    arm = robot.base_nv + np.array([robot.joint_index(j) for j in ARM_JOINTS])
    d = np.zeros(terms.M.shape[0])
    d[arm] = np.linalg.pinv(terms.J[:, arm]) @ -np.asarray(normal, dtype=float)
    return d


def standing_wrenches(robot: FloatingBaseModel, terms: FloatingBaseTerms) -> np.ndarray:
    """w (12): the least-norm foot wrenches with Jf_base^T w = g_base, the ground carrying the weight."""
    gravity = pin.computeGeneralizedGravity(robot.model, robot.data, terms.q)
    base = slice(robot.base_nv)
    return np.linalg.pinv(terms.Jf[:, base].T) @ gravity[base]


def cone_step(force0: np.ndarray, force1: np.ndarray, mu: float) -> float:
    """The largest s >= 0 with |f_xy| <= mu f_z for f = force0 + s force1: the smallest positive
    root of mu^2 f_z^2 - |f_xy|^2 and of f_z (the set is an interval, the cone being convex)."""
    a_xy, a_z, b_xy, b_z = force0[:2], force0[2], force1[:2], force1[2]
    if mu * a_z < np.linalg.norm(a_xy):
        return 0.0
    quadratic = [mu**2 * b_z**2 - b_xy @ b_xy, 2.0 * (mu**2 * a_z * b_z - a_xy @ b_xy), mu**2 * a_z**2 - a_xy @ a_xy]
    roots = [r.real for r in np.roots(np.trim_zeros(quadratic, "f")) if abs(r.imag) < 1e-12 and r.real > 0.0]
    if b_z < 0.0:
        roots.append(-a_z / b_z)
    return float(min(roots)) if roots else math.inf


def sole_rows(sole: np.ndarray, depth: float, impulse: np.ndarray) -> np.ndarray:
    """nu_e . (-tau_y, tau_x) - (nu_e . a_e) f_z for each edge e of the convex sole polygon
    ``sole`` lying ``depth`` below the foot frame (module docstring), for a foot wrench impulse
    (f, tau) about the foot frame, in the foot's axes: <= 0 keeps the centre of pressure in the
    sole."""
    f, tau = impulse[:3], impulse[3:]
    tau_sole = tau + np.cross([0.0, 0.0, depth], f)  # about the sole point under the frame
    return edge_normals(sole) @ np.array([-tau_sole[1], tau_sole[0]]) - edge_margins(sole, np.zeros(2)) * f[2]


def foot_bounds(robot: FloatingBaseModel, terms: FloatingBaseTerms, unit_feet: np.ndarray, setting: Setting):
    """The (b) bounds: ``foot_slip`` and ``foot_lift`` (module docstring) of every held contact,
    each with its own sole, depth and (unless ``setting.friction`` is given) friction."""
    standing = setting.impact_duration * standing_wrenches(robot, terms)
    placements = robot.frame_placements(terms.q)
    slip, lift = Bound(math.inf, ""), Bound(math.inf, "")
    for k, (foot, contact) in enumerate(zip(FEET, robot.description.held_contacts, strict=True)):
        R = placements[contact.frame].rotation
        sole = convex_hull(contact.sole)
        mu = contact.friction if setting.friction is None else setting.friction
        rows = slice(6 * k, 6 * k + 6)

        def local(w):
            return np.concatenate([R.T @ w[:3], R.T @ w[3:]])

        w0, w1 = local(standing[rows]), local(unit_feet[rows])
        s = cone_step(w0[:3], w1[:3], mu)
        if s < slip.speed:
            slip = Bound(s, foot)
        s = float(np.min(row_steps(sole_rows(sole, contact.depth, w0), sole_rows(sole, contact.depth, w1))))
        if s < lift.speed:
            lift = Bound(s, foot)
    return slip, lift


def joint_velocity_bound(robot: FloatingBaseModel, d: np.ndarray, dv: np.ndarray) -> Bound:
    """(a): 1 / max_i max(|d_i|, |(d + dv)_i|) / dq_max_i over the joints."""
    joints = slice(robot.base_nv, None)
    ratio = np.maximum(np.abs(d[joints]), np.abs(d[joints] + dv[joints])) / robot.dq_max
    i = int(np.argmax(ratio))
    return Bound(1.0 / ratio[i], robot.joint_names[i]) if ratio[i] > 0.0 else Bound(math.inf, "")


def closed_form_max_speed(
    robot: FloatingBaseModel, q: np.ndarray, normal, setting: Setting = Setting()
) -> HumanoidMaxSpeed:
    """The highest contact speed of the stance configuration q against the wall ``normal``
    (towards the robot) that satisfies (a), (b) and (c), and what binds (module docstring)."""
    if (setting.friction is not None and not setting.friction > 0.0) or not setting.impact_duration > 0.0:
        raise BadInputError("the foot friction and the impact duration must be > 0")
    normal = np.asarray(normal, dtype=float)
    terms = robot.terms(q)
    d = approach_direction(robot, terms, normal)
    v1 = terms.J @ d
    unit = predict(terms, setting.method, normal, v1, setting.restitution)
    slip, lift = foot_bounds(robot, terms, unit.feet_impulse, setting)
    region = capture_region(support_polygon(robot, q), terms.com)
    edges = capturable_speeds(terms, region, setting.method, normal, v1, setting.restitution)
    edge = int(np.argmin(edges))
    capture = float(edges[edge])
    bounds = {
        "joint_velocity": joint_velocity_bound(robot, d, unit.dv),
        "foot_slip": slip,
        "foot_lift": lift,
        "capture": Bound(capture, f"edge {edge}" if math.isfinite(capture) else ""),
    }
    criterion = min(CRITERIA, key=lambda c: bounds[c].speed)
    return HumanoidMaxSpeed(bounds[criterion].speed, criterion, bounds[criterion].where, bounds)
