"""What one simulated impact trial of any robot measured and predicted: :class:`TrialResult`.

Every robot's trial gives the same result: the trial's setting (its id, posture, commanded normal
speed and tangential velocity, the controller's jump constraints: a ``sim.runner.TrialSpec``'s),
its log as a robot logs it
(``controller.measured.trial_log``), the measured impact (``controller.measured.impact``: the
pre-impact state (q-, dq-), the contact start t_c, the contact impulse iota and duration), the
generalized-velocity jump it measured (nv: a floating base's base rows first), the contact speed
v_c = -n . J(q-) dq-, each predictor's jump at (q-, dq-) (``controller.model.jump``), and the
observed failure criteria of the robot's description (``sim.observed_criteria``: name ->
``Observed``), from which the ratios, failures, onsets and feasibility derive. The prediction
error per predictor is eq. (26), the mean of |predicted - measured| over the joints.

A robot with held contacts (the standing G1) measures more: the feet, the CoM and the wall's peak
force (:class:`HeldContactResult`, the result's ``held``; None for a fixed-base arm).

A fixed-base arm's impact is ``controller.measured.impact.measure_impact`` of its log
(``scenarios.trial.TrialRunner.evaluate``). A standing robot's (:func:`held_contact_result`) is
read from the wall force of the simulation (:class:`WallContact`): the state before the impact is
the last control step before the wall's first contact force, the state after it the first control
step after that first contiguous contact ends (at most :data:`WINDOW` s later). The measured
impulse is the integral of the wall force over that contact, and its peak (``peak_force``: the
largest normal wall force of a physics step); their ratio is the contact's equivalent duration
(``equivalent_duration``, the T of the closed form's foot criteria). The jump is compared over
the joints with each predictor of ``controller.model.jump`` fed its own impulse, and with the
feet-held momentum law fed the measured impulse (``momentum``). Its failure criteria
(``sim.observed_criteria``: joint velocity after the settling, foot slip and lift in the impact
window, capture, fell) each have an onset time, the same definitions as the closed form's criteria
(``controller.model.max_speed``) measured in the trial. The feet's displacements are kept beside
them: ``foot_slip`` / ``foot_lift`` (m), the largest horizontal / vertical motion of a foot frame
after the settling (``slipped`` / ``lifted``: beyond :data:`SLIP` / :data:`LIFT`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from impactqp.controller.measured.dataset import TrialEntry
from impactqp.controller.measured.impact import ImpactMeasurement
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.jump import jump_from_impulse, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS

from .humanoid_feet import SPEED
from .observed_criteria import Observed, TrialObservation, first_failure, observe
from .trial_loop import LoopRecord, ServoedPlant
from .trial_sources import TrialStart

SLIP = 0.005  # m of horizontal foot motion counted as a slip
LIFT = 0.005  # m of vertical foot motion counted as a lift
WINDOW = 0.03  # s: longest first contact read as a standing robot's impact


@dataclass(frozen=True)
class HeldContactResult:
    """What a trial of a robot with held contacts measures beyond every robot's: the wall's
    largest normal force of a physics step in the first contact (``peak_force``, N), the floor's
    impulse on the feet over it (N s), the measured and predicted CoM jumps (m/s), each
    predictor's impulse (N s), the CoM velocity after the first wall contact, the largest
    horizontal / vertical foot-frame displacements after the settling (``foot_slip`` /
    ``foot_lift``, m; ``slipped`` / ``lifted``: beyond :data:`SLIP` / :data:`LIFT`), the largest
    horizontal speed of a touching sole sphere in the impact window (0 when no sole carried weight
    before the contact: the robot was already falling), the wall (its plane's x and
    its normal towards the robot) and the Pinocchio configurations at the control rate."""

    peak_force: float
    floor_impulse: np.ndarray
    measured_com_jump: np.ndarray
    predicted_com_jump: dict
    predicted_impulse: dict
    post_com_velocity: np.ndarray
    foot_slip: float
    foot_lift: float
    slide_speed: float
    wall_x: float
    wall_normal: np.ndarray
    q_log: np.ndarray

    @property
    def slipped(self) -> bool:
        """A foot frame moved more than SLIP horizontally (the displacement measure)."""
        return self.foot_slip > SLIP

    @property
    def lifted(self) -> bool:
        """A foot frame moved more than LIFT vertically (the displacement measure)."""
        return self.foot_lift > LIFT


@dataclass(frozen=True)
class TrialResult:
    """One trial's setting, log, measured impact, predictions and observed criteria (module
    docstring; ``trial_id`` a file-name-safe id, ``jump_model`` None: the arm's controller without
    jump constraints, or a robot with held contacts); ``source`` names the command source
    (``sim.trial_sources``), ``record`` is what it kept of each control step (the QP's
    ``QpRecord``) or None, ``fallback_count`` the arm's controller's fallbacks."""

    trial_id: str
    posture: str
    normal_speed: float  # commanded (m/s)
    tangential_velocity: np.ndarray  # commanded (3) m/s
    jump_model: str | None
    log: TrialLog
    impact: ImpactMeasurement
    measured_jump: np.ndarray  # (nv) generalized-velocity jump, Pinocchio convention
    contact_speed: float
    predicted: dict[str, np.ndarray]  # predictor -> (nv) jump
    criteria: dict[str, Observed]
    source: str = ""
    record: object = None
    fallback_count: int = 0
    held: HeldContactResult | None = None

    @property
    def errors(self) -> dict[str, float]:
        """Predictor -> eq. (26): the mean |predicted - measured| over the joints."""
        joints = slice(len(self.measured_jump) - self.log.q.shape[1], None)
        measured = self.measured_jump[joints]
        return {m: float(np.mean(np.abs(dv[joints] - measured))) for m, dv in self.predicted.items()}

    def predicted_post_velocity(self, method: str) -> np.ndarray:
        """The joints' post-impact velocity predicted by ``method``: dq+ = dq- + Delta dq (eq.
        (19)), with the jump's joint part (its last n entries, after a floating base's twist)."""
        dq_pre = self.impact.dq_pre
        return dq_pre + self.predicted[method][-len(dq_pre):]

    @property
    def violated(self) -> bool:
        """A criterion failed."""
        return any(c.failed for c in self.criteria.values())

    @property
    def feasible(self) -> bool:
        """No criterion failed."""
        return not self.violated

    @property
    def failures(self) -> tuple:
        """Every criterion that failed, in the criteria's order."""
        return tuple(name for name, c in self.criteria.items() if c.failed)

    @property
    def failure_times(self) -> dict:
        """Failed criterion -> s from the first contact to its onset (< 0: before it)."""
        return {name: c.onset for name, c in self.criteria.items() if c.failed}

    @property
    def first_failure(self) -> str:
        """The criterion that failed first (``sim.observed_criteria.first_failure``), "" when none."""
        return first_failure(self.criteria)

    @property
    def failure_time(self) -> float:
        """s from the first contact to the first failure (nan: none)."""
        return self.failure_times.get(self.first_failure, float("nan"))

    @property
    def max_velocity_ratio(self) -> float:
        """The largest |dq_i| / dq_max_i of the joints in the watched window."""
        return self.criteria["joint_velocity"].value

    @property
    def max_velocity_joint(self) -> str:
        """The joint where it occurs."""
        return self.criteria["joint_velocity"].where

    @property
    def max_torque_ratio(self) -> float:
        """The largest impulsive torque over the torque limit (a fixed base's criterion)."""
        return self.criteria["impulsive_torque"].value

    @property
    def fell(self) -> bool:
        """The robot fell (a robot with held contacts' criterion)."""
        return self.criteria["fell"].failed

    @property
    def capture_margin(self) -> float:
        """m: the post-impact capture point's distance inside the support polygon (< 0: outside)."""
        return self.criteria["capture"].value

    @property
    def cone_ratio(self) -> float:
        """The largest |f_t| / (mu f_n) of a loaded foot in the impact window."""
        return self.criteria["foot_slip"].value

    @property
    def cop_margin(self) -> float:
        """m: the smallest centre-of-pressure margin of a loaded foot in the impact window."""
        return self.criteria["foot_lift"].value

    @property
    def commands(self) -> np.ndarray:
        """(steps, joints) the joint velocity commands sent to the servo (rad/s): the log's ``dq_cmd``."""
        return self.log.dq_cmd

    @property
    def equivalent_duration(self) -> float:
        """The first contact's equivalent duration (s) of a robot with held contacts: its normal
        impulse over its peak force, the length of a constant force at the peak that gives the same
        impulse (the closed form's T)."""
        return float(self.held.wall_normal @ self.impact.impulse) / self.held.peak_force

    def dataset_trial(self) -> tuple[TrialEntry, TrialLog]:
        """The manifest entry (its files, commanded speeds, posture and contact start) and the log
        of the trial in the dataset's world frame (with held contacts ``sim.generation``: the
        base's x minus the wall's)."""
        name = self.trial_id
        entry = TrialEntry(
            id=name, file=f"{name}.csv", reference_normal_speed=self.normal_speed, force_file=f"{name}_force.csv",
            reference_tangential_velocity=tuple(float(v) for v in self.tangential_velocity), posture=self.posture,
            impact_time=self.impact.t_contact_start,
        )
        if self.held is None:
            return entry, self.log
        base = self.log.base.copy()
        base[:, 0] -= self.held.wall_x
        return entry, replace(self.log, base=base)

    def to_json(self, robot: str | None = None) -> dict:
        """The ``impactqp simulate --json`` report; with held contacts that of the robot named ``robot``."""
        impact = self.impact
        if self.held is None:
            return {
                "posture": self.posture, "reference_normal_speed": self.normal_speed,
                "reference_tangential_velocity": self.tangential_velocity.tolist(), "jump_model": self.jump_model,
                "contact_speed": self.contact_speed, "impact_time": impact.t_contact_start,
                "impact_duration": impact.duration, "impulse": impact.impulse.tolist(),
                "dq_jump": self.measured_jump.tolist(),
                "predicted": {name: jump.tolist() for name, jump in self.predicted.items()},
                "max_velocity_ratio": self.max_velocity_ratio, "max_torque_ratio": self.max_torque_ratio,
                "violated": self.violated, "controller_fallbacks": self.fallback_count,
            }
        held = self.held
        return {
            "robot": robot, "posture": self.posture, "reference_speed": self.normal_speed,
            "contact_speed": self.contact_speed, "impulse": impact.impulse.tolist(),
            "floor_impulse": held.floor_impulse.tolist(), "impact_duration": impact.duration,
            "dq_jump": self.measured_jump.tolist(), "com_jump": held.measured_com_jump.tolist(),
            "predicted": {m: dv.tolist() for m, dv in self.predicted.items()},
            "predicted_com_jump": {m: c.tolist() for m, c in held.predicted_com_jump.items()},
            "errors": self.errors, "foot_slip": held.foot_slip, "foot_lift": held.foot_lift, "fell": self.fell,
            "max_velocity_ratio": self.max_velocity_ratio, "first_failure": self.first_failure,
            "violated": self.violated,
        }


@dataclass(frozen=True)
class WallContact:
    """The wall per control step: its impulse on the robot (steps, 3), the sum of its physics
    steps', and its largest normal force of a physics step (steps,) (N, 0 without one); the
    control step of the first wall contact and the control period (s)."""

    forces: np.ndarray
    peaks: np.ndarray
    first: int
    control_period: float

    @classmethod
    def of(cls, record: LoopRecord, plant: ServoedPlant, start: TrialStart) -> WallContact | None:
        """The wall of a trial's loop record on ``plant`` from ``start`` (its wall's normal,
        towards the robot, and its control period); None when it was never touched."""
        if record.first_contact is None:
            return None
        walls = record.force.reshape(len(record.t), plant.substeps, 3)
        forces = (walls * plant.scene.timestep).sum(axis=1)
        peaks = np.maximum((walls @ start.surface.normal).max(axis=1), 0.0)
        return cls(forces, peaks, record.first_contact, start.control_period)

    @property
    def last(self) -> int:
        """The last control step of the first contiguous contact (at most WINDOW s long)."""
        last, window = self.first, int(round(WINDOW / self.control_period))
        while last + 1 < min(len(self.forces), self.first + window) and np.any(self.forces[last + 1] != 0.0):
            last += 1
        return last


def held_contact_result(stance: str, start: TrialStart, contact: WallContact, run, source: str) -> TrialResult:
    """The measured impact, the predicted jumps and the observed criteria (module docstring) of
    the trial ``run`` (``sim.runner.TrialRun``) of a robot with held contacts in the stance
    ``stance``, started at ``start`` (its wall, commanded speed, settling time and control
    period), driven by the command source named ``source``."""
    robot, log, held, dt = start.robot, run.log, run.record.held, start.control_period
    normal = start.surface.normal
    first, last = contact.first, contact.last
    settled = int(round(start.settle / dt))
    watched = np.arange(len(log)) >= settled
    terms = robot.terms(np.concatenate([log.base[first, :robot.base_nq], log.q[first]]))
    o = TrialObservation(
        robot, log, watched, first, last, contact.forces[first:last + 1].sum(axis=0), (last + 1 - first) * dt, terms.J,
        dt, held,
    )
    q_pre, v_pre = o.state(first)
    q_post, v_post = o.state(o.post)
    impulse = o.impulse
    v_minus = terms.J @ v_pre
    measured = v_post - v_pre
    predicted, com, impulses = {}, {}, {}
    for method in HELD_CONTACT_METHODS:
        jump = predict(terms, method, normal, v_minus)
        predicted[method], com[method], impulses[method] = jump.dq_jump, jump.com_jump, jump.impulse
    predicted["momentum"] = jump_from_impulse(terms, impulse)
    com["momentum"] = terms.Jcom @ predicted["momentum"]
    impulses["momentum"] = impulse
    post_com_velocity = robot.terms(q_post).Jcom @ v_post
    joints = slice(robot.base_nv, None)
    t_contact = first * dt
    impact = ImpactMeasurement(
        "force", t_contact, t_contact, first, first, o.post, (first, last), q_pre[robot.base_nq:], v_pre[joints],
        v_post[joints], measured[joints], impulse, o.duration,
    )
    soles = held.soles[o.impact_window()]
    moved = held.feet[settled:] - held.feet[settled]
    feet = HeldContactResult(
        peak_force=float(contact.peaks[first:last + 1].max()), floor_impulse=held.floor[first:last + 1].sum(axis=0),
        measured_com_jump=post_com_velocity - terms.Jcom @ v_pre, predicted_com_jump=com, predicted_impulse=impulses,
        post_com_velocity=post_com_velocity, foot_slip=float(np.linalg.norm(moved[..., :2], axis=-1).max()),
        foot_lift=float(np.abs(moved[..., 2]).max()), slide_speed=float(soles[:, o.loaded_before(), SPEED].max(initial=0.0)),
        wall_x=float(start.surface.point[0]), wall_normal=normal.copy(),
        q_log=np.column_stack([log.base[:, :robot.base_nq], log.q]),
    )
    return TrialResult(
        trial_id=f"{stance}_vn{round(start.speed * 1000):d}_{source}", posture=stance, normal_speed=start.speed,
        tangential_velocity=np.zeros(3), jump_model=None, log=log, impact=impact, measured_jump=measured,
        contact_speed=float(-normal @ v_minus), predicted=predicted, criteria=observe(o), source=source,
        record=run.driver.record, held=feet,
    )
