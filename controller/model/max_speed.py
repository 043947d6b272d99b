"""Closed-form highest feasible contact speed of a posture, for every robot (docs/max-speed.md,
docs/floating-base.md).

The approach motion at speed v is dq- = v d: the contact point moves along -n (v- = J d v = -v n).
For a fixed-base arm every joint moves and the contact frame does not rotate, d = J6+ [-n; 0]
(J6 the 6 x nv world-aligned frame Jacobian, + the pseudo-inverse); for a robot with held
contacts (a standing humanoid's soles) the contact's arm moves alone (its description's ``contact.joints``),
d_arm = J_arm+ (-n), the body at rest. Every predicted quantity is linear in v (the jump at unit
speed dv, the contact impulse iota and the held contacts' impulsive wrenches lambda: the arm's
``jump`` model, eqs. 6 and 12, or ``jump.predict`` with the contacts held), so each
criterion is an inequality in v whose feasible set is an interval [0, v_max]; the highest
feasible speed is the smallest v_max, and the criterion giving it binds.

The criteria are a list chosen by the robot's description (:func:`criteria_of`):

- every joint's velocity: ``velocity_pre`` |d_i| v <= dq_max_i and ``velocity_post``
  |(d + dv)_i| v <= dq_max_i, and ``impulsive_torque`` |J^T iota|_i / delta_t <= tau_max_i,
  the arm's (:data:`CRITERIA`); a robot with held contacts checks both velocities as one
  ``joint_velocity`` criterion;
- with held contacts (:data:`HELD_CONTACT_CRITERIA`), the feet, held during the impulse, at the
  peak of the hand's force: the force peaks at iota / T, T the contact's equivalent duration
  (its impulse over its peak force), and the ground's wrench on foot k is then F_k(v) / T with
  F_k(v) = T w_k + v lambda_k, w_k the standing wrench (the least-norm foot wrenches carrying the
  robot's weight; world axes, about the foot frame). The criteria are homogeneous in F_k, so they
  are checked on F_k. Assumed plainly: the feet's impulsive wrenches peak with the hand's force,
  in the feet-held model's proportions, and the feet are flat.
  ``foot_slip``: |F_xy| <= mu F_z (the friction cone of the summed impulse; a quadratic in v;
  mu the held contact's ``friction`` unless the setting gives one for every foot).
  ``foot_lift``: the centre of pressure of F, about the sole (the held contact's ``depth`` below
  the frame), stays inside the convex hull of the sole's corners (``sole``):
  nu_e . (-tau_y, tau_x) <= (nu_e . a_e) f_z for each edge e (outward normal nu_e, corner a_e);
  together these also give f_z >= 0.
  ``capture``: the post-impact CoM velocity stays in the zero-step capture region
  (``capture.capturable_speeds``, the smallest over the edges).

:func:`closed_form_max_speeds` evaluates the arm's criteria for N postures at once on the batched
terms and predictor of ``controller.model.jump`` (stacked pseudo-inverses, Cholesky solves with M).

With friction, an arm's highest speed is ``friction_max_speed.frictional_max_speed``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .batch import BatchTerms, predict_from_terms
from .capture import com_jump_map, row_steps, support_capture_region
from .humanoid_stance import convex_hull, edge_margins, edge_normals
from .jump import predict
from .model_terms import ModelTerms
from .robot import RobotModel
from .robot_description import RobotDescription
from .validation import impact_duration, positive, restitution, unit_normal

DEFAULT_IMPACT_DURATION = 0.015  # s: delta_t of an arm's impact
HAND_IMPACT_DURATION = 0.0034  # s: T, the wall contact's equivalent duration (impulse / peak force; the simulated wall's) of a robot with held contacts


@dataclass(frozen=True)
class Setting:
    """What the closed form assumes: predictor (a name of ``jump.JUMP_MODELS``, or of
    ``jump_kernels.HELD_CONTACT_METHODS`` with held contacts), restitution, friction mu of every held contact
    (None: each held contact's own ``friction``, the description's) and impact duration (s; None:
    the robot's, :data:`DEFAULT_IMPACT_DURATION`, or :data:`HAND_IMPACT_DURATION` with held contacts)."""

    method: str = "crb"
    restitution: float = 0.0
    friction: float | None = None
    impact_duration: float | None = None

    def __post_init__(self):
        """BadInputError for a restitution outside [0, 1], a friction that is not > 0 or an
        impact duration outside its range (``validation.impact_duration``)."""
        restitution(self.restitution)
        if self.friction is not None:
            positive(self.friction, "the foot friction")
        if self.impact_duration is not None:
            impact_duration(self.impact_duration)

    def duration(self, robot: RobotDescription) -> float:
        """delta_t (T): the setting's, else the robot's."""
        if self.impact_duration is not None:
            return self.impact_duration
        return HAND_IMPACT_DURATION if robot.held_contacts else DEFAULT_IMPACT_DURATION


@dataclass(frozen=True)
class Bound:
    """One criterion's highest feasible speed (m/s, inf when it never binds) and where it binds:
    a joint name (``joint``: its 1-based index), a foot (left, right) or an edge of the support
    polygon ("edge k")."""

    speed: float
    where: str = ""
    joint: int = 0


@dataclass(frozen=True)
class MaxSpeed:
    """The highest feasible contact speed, the criterion that binds it ("" when none does), where
    (:class:`Bound`), and every criterion's bound."""

    speed: float
    criterion: str
    where: str
    joint: int  # 1-based index of the binding joint, 0 when no joint binds
    bounds: dict  # criterion -> Bound

    def to_json(self) -> dict:
        def finite(x):
            return x if math.isfinite(x) else None

        return {
            "speed": finite(self.speed), "criterion": self.criterion, "where": self.where,
            "bounds": {c: {"speed": finite(b.speed), "where": b.where} for c, b in self.bounds.items()},
        }


class ImpactPart(NamedTuple):
    """The part of an approach that does not scale with the normal speed v (a slide along the
    surface, ``friction_max_speed``): its joint velocity d_t (nv), jump (nv), contact impulse (3)
    and the held contacts' impulsive wrenches (6 each)."""

    direction: np.ndarray
    jump: np.ndarray
    impulse: np.ndarray
    held_impulse: np.ndarray


@dataclass(frozen=True)
class UnitImpact:
    """The approach of one posture at unit speed and what the predictor gives for it: d (nv),
    the jump dv (nv), the contact impulse iota (3) and the held contacts' impulsive wrenches
    lambda (6 each, world axes about each frame; none without held contacts); with a ``start``
    (:class:`ImpactPart`; None: the approach from rest) each quantity is start + v (unit's), affine
    in the normal speed v, and the criteria bound that affine path."""

    robot: RobotModel
    terms: ModelTerms
    normal: np.ndarray
    setting: Setting
    direction: np.ndarray
    jump: np.ndarray
    impulse: np.ndarray
    held_impulse: np.ndarray
    start: ImpactPart | None = None

    @property
    def joints(self) -> slice:
        """The joints' entries of a generalized velocity (after a floating base's)."""
        return slice(self.direction.shape[0] - self.robot.dq_max.shape[0], None)


def contact_joints(description: RobotDescription) -> tuple[str, ...]:
    """The joints that move a robot's own contact point in a scripted approach: its description's
    ``contact.joints``, or every joint."""
    contact = description.contact
    return contact.joints if contact is not None and contact.joints else description.joints


def approach_direction(robot: RobotModel, terms, normal) -> np.ndarray:
    """d (nv): the joint velocity per unit approach speed along -n (module docstring): J6+ [-n; 0]
    for an arm, J_arm+ (-n) on the joints that move the contact (its description's
    ``contact.joints``; every joint when it names none) and zero elsewhere with held contacts."""
    return contact_motion(robot, terms, -np.asarray(normal, dtype=float))


def contact_motion(robot: RobotModel, terms, velocity: np.ndarray) -> np.ndarray:
    """The joint velocity (nv) that moves the contact point at ``velocity`` (3) without turning
    it: J6+ [velocity; 0] for an arm, J_arm+ velocity on the contact's joints with held contacts
    (:func:`approach_direction`)."""
    if not robot.description.held_contacts:
        return np.linalg.pinv(terms.J6) @ np.concatenate([velocity, np.zeros(3)])
    arm = robot.base_nv + np.array([robot.joint_index(j) for j in contact_joints(robot.description)])
    d = np.zeros(terms.M.shape[0])
    d[arm] = np.linalg.pinv(terms.J[:, arm]) @ velocity
    return d


def unit_impact(robot: RobotModel, terms, normal: np.ndarray, setting: Setting) -> UnitImpact:
    """The approach d and its predicted impact at unit speed (v- = J d): ``jump.predict``
    (iota = G J d, dv = K iota, and the held contacts' impulse when the robot holds any)."""
    d = approach_direction(robot, terms, normal)
    unit = predict(terms, setting.method, normal, terms.J @ d, setting.restitution)
    return UnitImpact(robot, terms, normal, setting, d, unit.dq_jump, unit.impulse, unit.held_impulse)


def joint_bound(robot: RobotModel, ratio: np.ndarray) -> Bound:
    """1 / max_i ratio_i over the joints, at the joint that gives it (inf when every ratio is 0)."""
    i = int(np.argmax(ratio))
    if not ratio[i] > 0.0:
        return Bound(math.inf)
    return Bound(float(1.0 / ratio[i]), robot.description.joints[i], i + 1)


def velocity_pre_ratio(u: UnitImpact) -> np.ndarray:
    """|d_i| / dq_max_i."""
    return np.abs(u.direction[u.joints]) / u.robot.dq_max


def velocity_post_ratio(u: UnitImpact) -> np.ndarray:
    """|(d + dv)_i| / dq_max_i."""
    return np.abs((u.direction + u.jump)[u.joints]) / u.robot.dq_max


def impulsive_torque_ratio(u: UnitImpact) -> np.ndarray:
    """|J^T iota|_i / delta_t / tau_max_i."""
    return np.abs((u.terms.J.T @ u.impulse)[u.joints]) / u.setting.duration(u.robot.description) / u.robot.tau_max


def joint_velocity_ratio(u: UnitImpact) -> np.ndarray:
    """max(|d_i|, |(d + dv)_i|) / dq_max_i: before and after the impact at once."""
    d, post = u.direction[u.joints], (u.direction + u.jump)[u.joints]
    return np.maximum(np.abs(d), np.abs(post)) / u.robot.dq_max


def affine_bound(robot: RobotModel, start: np.ndarray, slope: np.ndarray, limit: np.ndarray) -> Bound:
    """The largest v >= 0 with |start + v slope| <= limit on every joint (0 when v = 0 already
    violates it), at the joint that gives it."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        speeds = np.where(slope > 0.0, (limit - start) / slope, np.where(slope < 0.0, (limit + start) / -slope, np.inf))
    speeds = np.where(np.abs(start) > limit, 0.0, speeds)
    i = int(np.argmin(speeds))
    return Bound(float(speeds[i]), robot.description.joints[i], i + 1) if math.isfinite(speeds[i]) else Bound(math.inf)


def joint_velocity(u: UnitImpact) -> Bound:
    """Every joint's velocity before and after the impact within its limit: 1 / the largest
    :func:`joint_velocity_ratio` from rest, else the smaller :func:`affine_bound` of dq- and dq+."""
    if u.start is None:
        return joint_bound(u.robot, joint_velocity_ratio(u))
    s, joints, limit = u.start, u.joints, u.robot.dq_max
    pre = affine_bound(u.robot, s.direction[joints], u.direction[joints], limit)
    post = affine_bound(u.robot, (s.direction + s.jump)[joints], (u.direction + u.jump)[joints], limit)
    return min(pre, post, key=lambda b: b.speed)


def standing_wrenches(robot: RobotModel, terms: ModelTerms) -> np.ndarray:
    """w (6 per held contact): the least-norm foot wrenches with Jf_base^T w = g_base, the ground
    carrying the weight (:func:`weight_wrenches` at the terms' state)."""
    return weight_wrenches(robot, terms.q, terms.held_jacobian)


def weight_wrenches(robot: RobotModel, q: np.ndarray, held_jacobian: np.ndarray) -> np.ndarray:
    """The least-norm held-contact wrenches w with Jf_base^T w = g_base at the configuration q,
    Jf = ``held_jacobian``: the ground carrying the weight."""
    gravity = pin.computeGeneralizedGravity(robot.model, robot.data, q)
    base = slice(robot.base_nv)
    return np.linalg.pinv(held_jacobian[:, base].T) @ gravity[base]


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


def foot_wrenches(u: UnitImpact) -> list:
    """(foot, held contact, T w_k, lambda_k) of every held contact, the wrenches in the foot's axes
    (T w_k plus the start's impulsive wrench with a ``start``)."""
    standing = u.setting.duration(u.robot.description) * standing_wrenches(u.robot, u.terms)
    if u.start is not None:
        standing = standing + u.start.held_impulse
    placements = u.robot.frame_placements(u.terms.q)
    feet = []
    for k, contact in enumerate(u.robot.description.held_contacts):
        foot = contact.label
        R = placements[contact.frame].rotation
        rows = slice(6 * k, 6 * k + 6)

        def local(w):
            return np.concatenate([R.T @ w[:3], R.T @ w[3:]])

        feet.append((foot, contact, local(standing[rows]), local(u.held_impulse[rows])))
    return feet


def foot_slip(u: UnitImpact) -> Bound:
    """The friction cone of every held contact (its own friction unless the setting gives one)."""
    slip = Bound(math.inf)
    for foot, contact, w0, w1 in foot_wrenches(u):
        mu = contact.friction if u.setting.friction is None else u.setting.friction
        s = cone_step(w0[:3], w1[:3], mu)
        if s < slip.speed:
            slip = Bound(s, foot)
    return slip


def foot_lift(u: UnitImpact) -> Bound:
    """The centre of pressure of every held contact inside its sole."""
    lift = Bound(math.inf)
    for foot, contact, w0, w1 in foot_wrenches(u):
        sole = convex_hull(contact.sole)
        s = float(np.min(row_steps(sole_rows(sole, contact.depth, w0), sole_rows(sole, contact.depth, w1))))
        if s < lift.speed:
            lift = Bound(s, foot)
    return lift


def capture(u: UnitImpact) -> Bound:
    """The post-impact CoM velocity dc+ = C iota (the pre-impact one taken as zero:
    ``capture.capturable_speeds``) inside the zero-step capture region (smallest over the edges)."""
    region = support_capture_region(u.robot, u.terms.q, u.terms.com)
    C = com_jump_map(u.terms)
    offset = -region.margins(np.zeros(2))
    if u.start is not None:
        offset = offset + region.A @ (C @ u.start.impulse)[:2]
    edges = row_steps(offset, region.A @ (C @ u.impulse)[:2])
    edge = int(np.argmin(edges))
    speed = float(edges[edge])
    return Bound(speed, f"edge {edge}" if math.isfinite(speed) else "")


def joint_criterion(ratio: Callable[[UnitImpact], np.ndarray]) -> Callable[[UnitImpact], Bound]:
    """The criterion on every joint whose ratio to the limit at unit speed is ``ratio``."""
    return lambda u: joint_bound(u.robot, ratio(u))


JOINT_RATIOS = {
    "velocity_pre": velocity_pre_ratio,
    "velocity_post": velocity_post_ratio,
    "impulsive_torque": impulsive_torque_ratio,
}
"""The per-joint ratios of an arm's criteria (module docstring)."""
CRITERIA_WITHOUT_HELD_CONTACTS = {name: joint_criterion(ratio) for name, ratio in JOINT_RATIOS.items()}
CRITERIA_WITH_HELD_CONTACTS = {
    "joint_velocity": joint_velocity,
    "foot_slip": foot_slip,
    "foot_lift": foot_lift,
    "capture": capture,
}
CRITERIA = tuple(CRITERIA_WITHOUT_HELD_CONTACTS)
HELD_CONTACT_CRITERIA = tuple(CRITERIA_WITH_HELD_CONTACTS)


def criteria_of(robot: RobotDescription) -> dict[str, Callable[[UnitImpact], Bound]]:
    """The criteria of the robot, in the order ties are broken: the joints' (:data:`CRITERIA`),
    or the joints' and the held contacts' (:data:`HELD_CONTACT_CRITERIA`) when it holds some."""
    return CRITERIA_WITH_HELD_CONTACTS if robot.held_contacts else CRITERIA_WITHOUT_HELD_CONTACTS


def criterion_slopes(robot: RobotModel, terms: ModelTerms, normal, setting: Setting = Setting()) -> dict[str, np.ndarray]:
    """Per-joint ratio to the limit at unit approach speed of each of an arm's criteria (a), (b), (c)."""
    unit = unit_impact(robot, terms, np.asarray(normal, dtype=float), setting)
    return {name: ratio(unit) for name, ratio in JOINT_RATIOS.items()}


def closed_form_max_speed(
    robot: RobotModel, terms, normal, setting: Setting = Setting()
) -> MaxSpeed:
    """The highest contact speed of the posture of ``terms`` (``robot.terms(q)``) against the
    surface ``normal`` (towards the robot) that meets every criterion of the robot
    (:func:`criteria_of`), and what binds (module docstring)."""
    unit = unit_impact(robot, terms, unit_normal(normal), setting)
    bounds = {name: criterion(unit) for name, criterion in criteria_of(robot.description).items()}
    criterion = min(bounds, key=lambda c: bounds[c].speed)
    best = bounds[criterion]
    if not math.isfinite(best.speed):
        return MaxSpeed(math.inf, "", "", 0, bounds)
    return MaxSpeed(best.speed, criterion, best.where, best.joint, bounds)


@dataclass(frozen=True)
class MaxSpeeds:
    """:class:`MaxSpeed` of N postures of an arm: speed (N,), index into CRITERIA (N,; -1 when
    nothing binds) and 1-based joint (N,; 0 when nothing binds)."""

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
    robot: RobotModel,
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
