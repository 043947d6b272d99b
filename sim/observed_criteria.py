"""The failure criteria observed in a simulated trial, one list chosen by the robot's description
(the observed side of ``controller.model.max_speed.criteria_of``; docs/max-speed.md,
docs/floating-base.md).

Every criterion reads a :class:`TrialObservation` (the trial's log, the control steps it watches,
the first wall contact) and gives an :class:`Observed`: its value, whether it failed and its
onset, the time from the first wall contact to the first watched control step at which it fails
(nan when it never does). A trial is feasible when no criterion of its robot failed.

- ``joint_velocity`` (every robot): the largest |dq_i(t)| / dq_max_i over the watched steps
  (where: the joint); fails above 1;
- ``impulsive_torque`` (a robot without held contacts, as in the closed form; a standing robot
  has no torque rows): max_i |J(q-)^T iota|_i / delta_t / tau_max_i, with iota the wall impulse
  and delta_t the contact's duration; fails above 1, at the contact;
- with held contacts (the standing robot's feet), during the impact window (the first contiguous
  wall contact and :data:`ONSET_AFTER` s after it), of a foot that carried weight at the control
  step before the contact (``sim.humanoid_feet``):
  ``foot_slip``: the foot's ground force on its friction cone, or its sole sliding (value: the
  largest cone ratio |f_t| / (mu f_n));
  ``foot_lift``: its centre of pressure on an edge of its sole (value: the smallest margin, m);
- ``capture``: the CoM velocity after the first contact outside the zero-step capture region of
  the measured CoM and support polygon (value: the capture point's margin, m; < 0 fails);
- ``fell``: the base below half its start height or tilted more than 45 degrees, or, at the last
  step, both the CoM's ground projection and the capture point outside the support polygon
  (:func:`falling_at_the_end`). No closed-form criterion: the outcome a failed capture risks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.capture import support_capture_region, support_heights
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import RobotDescription

from .humanoid_feet import CONE, LOAD, MARGIN, HeldContactLog, lift_onset, slip_onset

ONSET_AFTER = 0.005  # s after the first wall contact ends in which foot onsets still count


@dataclass(frozen=True)
class TrialObservation:
    """What the criteria read of one trial: the robot, its log (a floating base's state in its
    base columns), the control steps the criteria watch (``watched``, a mask), the first and last
    control steps of the first wall contact, the wall impulse over it (N s) and its duration (s),
    the contact Jacobian J (3 x nv) before it, the control period (s) and, with held contacts,
    their log."""

    robot: RobotModel
    log: TrialLog
    watched: np.ndarray
    first: int
    last: int
    impulse: np.ndarray
    duration: float
    contact_jacobian: np.ndarray
    control_period: float
    held: HeldContactLog | None = None

    def state(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The Pinocchio state (q, v) of control step k (a floating base's coordinates first)."""
        base_nq, log = self.robot.base_nq, self.log
        if not base_nq:
            return log.q[k], log.dq[k]
        return np.concatenate([log.base[k, :base_nq], log.q[k]]), np.concatenate([log.base[k, base_nq:], log.dq[k]])

    @property
    def post(self) -> int:
        """The control step after the first contact (the trial's last when it ends sooner)."""
        return min(self.last + 1, len(self.log) - 1)

    def impact_window(self) -> np.ndarray:
        """(steps,) the first contact and ONSET_AFTER s after it."""
        window = np.zeros(len(self.log), dtype=bool)
        window[self.first:self.last + 1 + int(round(ONSET_AFTER / self.control_period))] = True
        return window

    def loaded_before(self) -> np.ndarray:
        """(feet,) the held contacts that carried weight at the control step before the contact."""
        return self.held.soles[self.first - 1, :, LOAD] > 0.0

    def onset(self, flags: np.ndarray) -> float:
        """s from the first contact to the first watched step of ``flags`` (nan: none)."""
        flags = flags & self.watched
        return (int(np.argmax(flags)) - self.first) * self.control_period if flags.any() else float("nan")


@dataclass(frozen=True)
class Observed:
    """One criterion as observed in a trial (module docstring); ``where``: the joint, or empty."""

    name: str
    value: float
    failed: bool
    onset: float
    where: str = ""


class JointVelocity:
    """``joint_velocity``: the largest |dq_i| / dq_max_i over the watched steps (module docstring)."""

    name = "joint_velocity"

    def observe(self, o: TrialObservation) -> Observed:
        ratios = np.abs(o.log.dq[o.watched]) / o.robot.dq_max
        per_step = np.zeros(len(o.log))
        per_step[o.watched] = ratios.max(axis=1)
        value = float(ratios.max())
        joint = o.robot.joint_names[int(np.argmax(ratios.max(axis=0)))]
        return Observed(self.name, value, value > 1.0, o.onset(per_step > 1.0), joint)


class ImpulsiveTorque:
    """``impulsive_torque``: max_i |J(q-)^T iota|_i / delta_t / tau_max_i (module docstring)."""

    name = "impulsive_torque"

    def observe(self, o: TrialObservation) -> Observed:
        torque = np.abs(o.contact_jacobian.T @ o.impulse) / o.duration
        value = float(np.max(torque / o.robot.tau_max))
        return Observed(self.name, value, value > 1.0, 0.0 if value > 1.0 else float("nan"))


class FootSlip:
    """``foot_slip``: a loaded foot slides in the impact window (module docstring)."""

    name = "foot_slip"

    def observe(self, o: TrialObservation) -> Observed:
        window, loaded = o.impact_window(), o.loaded_before()
        flags = window & np.any(slip_onset(o.held.soles) & loaded, axis=1)
        value = float(o.held.soles[window][:, loaded, CONE].max(initial=0.0))  # 0: no foot was loaded (already falling)
        onset = o.onset(flags)
        return Observed(self.name, value, not np.isnan(onset), onset)


class FootLift:
    """``foot_lift``: a loaded foot's centre of pressure reaches an edge in the impact window
    (module docstring)."""

    name = "foot_lift"

    def observe(self, o: TrialObservation) -> Observed:
        window, loaded = o.impact_window(), o.loaded_before()
        flags = window & np.any(lift_onset(o.held.soles) & loaded, axis=1)
        value = float(o.held.soles[window][:, loaded, MARGIN].min(initial=np.inf))  # inf: no foot was loaded
        onset = o.onset(flags)
        return Observed(self.name, value, not np.isnan(onset), onset)


def capture_margin(robot: RobotModel, q: np.ndarray, com_velocity: np.ndarray) -> float:
    """The capture point's smallest distance (m) inside the support polygon of the configuration q
    for the CoM velocity ``com_velocity`` (``controller.model.capture``; < 0: a step is needed);
    -inf for a robot whose CoM is not above its soles (fallen: nothing captures it)."""
    com = robot.terms(q).com
    if com[2] <= max(0.0, support_heights(robot, q).max()):
        return -np.inf
    region = support_capture_region(robot, q, com)
    return float(region.margins(com_velocity).min())


def falling_at_the_end(robot: RobotModel, state) -> bool:
    """Whether the robot in ``state`` (q, v), its pelvis still up, is falling: its CoM's ground
    projection and its capture point are both outside the support polygon of its feet
    (``capture_margin`` < 0 at rest and at its CoM velocity)."""
    q, v = state
    outside = capture_margin(robot, q, np.zeros(3)) < 0.0
    return outside and capture_margin(robot, q, robot.terms(q).Jcom @ v) < 0.0


class Capture:
    """``capture``: the CoM velocity after the first contact is capturable (module docstring)."""

    name = "capture"

    def observe(self, o: TrialObservation) -> Observed:
        q, v = o.state(o.post)
        margin = capture_margin(o.robot, q, o.robot.terms(q).Jcom @ v)
        flags = np.zeros(len(o.log), dtype=bool)
        flags[o.post] = margin < 0.0
        onset = o.onset(flags)
        return Observed(self.name, margin, not np.isnan(onset), onset)


class Fell:
    """``fell``: the base low or tilted, or falling at the end (module docstring)."""

    name = "fell"

    def observe(self, o: TrialObservation) -> Observed:
        base, base_nq = o.log.base, o.robot.base_nq
        height = base[:, 2]
        up = np.array([pin.Quaternion(b[3:base_nq]).matrix()[2, 2] for b in base])
        fell = (height < 0.5 * height[0]) | (up < np.cos(np.radians(45.0)))
        if not fell.any():
            fell[-1] = falling_at_the_end(o.robot, o.state(len(o.log) - 1))
        onset = o.onset(fell)
        return Observed(self.name, float(not np.isnan(onset)), not np.isnan(onset), onset)


WITHOUT_HELD_CONTACTS = (JointVelocity(), ImpulsiveTorque())
WITH_HELD_CONTACTS = (JointVelocity(), FootSlip(), FootLift(), Capture(), Fell())


def observed_criteria(robot: RobotDescription) -> tuple:
    """The criteria observed in a trial of ``robot``, in the order ties are broken: the joints'
    (velocity and impulsive torque), or, when it holds contacts, the joints' velocity and the held
    contacts' (module docstring)."""
    return WITH_HELD_CONTACTS if robot.held_contacts else WITHOUT_HELD_CONTACTS


def observe(observation: TrialObservation) -> dict[str, Observed]:
    """Every criterion of the observed robot, by name, in the order of :func:`observed_criteria`."""
    return {c.name: c.observe(observation) for c in observed_criteria(observation.robot.description)}


def first_failure(criteria: dict[str, Observed]) -> str:
    """The criterion that failed first (ties: the first in the list), "" when none failed."""
    failed = [c for c in criteria.values() if c.failed]
    order = list(criteria)
    return min(failed, key=lambda c: (c.onset, order.index(c.name))).name if failed else ""
