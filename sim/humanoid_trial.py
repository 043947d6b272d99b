"""One simulated hand impact of the standing G1, and a campaign of them (docs/floating-base.md).

Trial: the robot starts at rest in a stance (``controller.model.humanoid_stance``), the wall
the source's ``gap`` beyond its contact point. It stands still for :data:`SETTLE` s, then the right arm
(shoulder, elbow, wrist: its description's ``contact.joints``) is driven so that the hand moves along +x at ``speed``:
dq_arm = J_arm^+ v* (J_arm the arm joints' block of the contact Jacobian), reached by a 20 ms velocity
ramp; every other joint is commanded at rest. At the first wall contact (plus a 5 ms detection
latency) the arm stops: the servo's reference is re-anchored at the measured joint positions, at
rest (``ComputedTorqueServo.hold``), and the command is zero from then on; the trial goes on for :data:`AFTER` s
to see whether the robot stands. Why re-anchor rather than only command zero velocity: the wall has
already stopped the hand, but the reference still moves at the approach speed, so a zero command
asks the servo for the reference's whole deceleration -dq_ref/dt in one control step; the waist and
shoulder torques saturate and the reaction jolts the feet (what that stop did: docs/results.md,
"G1: servo and stop"). Re-anchored, the servo only damps the joints' post-impact velocities.
That is the default command source (``sim.trial_sources.SCRIPTED``); ``source`` chooses another
one, e.g. the whole-body QP (``sim.trial_sources.QpCommand``): a source (``TrialSource``) gives its
start gap, the time it may take to reach the wall (``approach_time``), per trial a driver, the
command source of the one trial loop (``sim.trial_loop``: ``step(q, v)`` returns the joints'
velocity command, ``stop()`` tells it that LATENCY has passed since the first contact), and whether
the servo re-anchors its reference at the stop (``holds_at_stop``). The trial runs in the one
trial runner of every robot (``sim.runner.run_impact``).

Servo (the kinematic control, the arm's: ``sim.servo.ComputedTorqueServo``, standing on the feet
through ``sim.servo.StandingSupport``): a joint-space computed-torque PD with acceleration
feed-forward on the joints, tau = M_f (ddq_ref + w^2 e + 2 w de) + h_j - tau_feet, with M_f the
joints' inertia with the base floating and tau_feet the joint torques of the least-norm foot
wrenches that carry the robot's weight in the measured configuration (every control step: the
weight's share between the feet and their moments follow the posture, which the whole-body QP
leans; wrenches of the start stance would leave the ankles a steady tracking error). The torque
each joint gets is clipped at its URDF effort limit (5-139 N m).

Plant: MuJoCo's G1 with the actuators' reflected rotor inertias by default (``armature``:
``sim.scene.plant_armature``; 0 for the link-only plant). The servo's M_f includes them
(MuJoCo's M does); the predictors do not (they keep the URDF model).

Measurement: the state before the impact is the last control step before the wall's first
contact force, the state after it the first control step after that first contiguous contact
ends (at most :data:`WINDOW` s later). The measured impulse is the integral of the wall force over
that contact, and its peak (``peak_force``: the largest normal wall force of a physics step);
their ratio is the contact's equivalent duration (``equivalent_duration``, the T of the closed
form's foot criteria). The jump is compared over the joints with each predictor of
``controller.model.jump`` fed its own impulse, and with the feet-held momentum law fed
the measured impulse (``momentum``); the error is eq. (26), the mean of |predicted - measured|.

Failures: the criteria of a robot with held contacts (``sim.observed_criteria``: joint velocity
after the settling, foot slip and lift in the impact window, capture, fell), each with its onset
time, the same definitions as the closed form's criteria (``controller.model.max_speed``) measured
in the trial; ``ImpactTrial.criteria`` lists them, the failures and their onsets derive from it.

Log: ``ImpactTrial.log`` holds the trial as a robot logs it (``controller.measured.trial_log``): per control
step the joints' state, the servo's torque held over the step, the command, the base state, and the wall
force per physics step (``sim.generation`` writes it as a dataset).

The feet's displacements are kept beside them: ``foot_slip`` / ``foot_lift`` (m), the largest
horizontal / vertical motion of a foot frame after the settling (``slipped`` / ``lifted``: beyond
:data:`SLIP` / :data:`LIFT`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from impactqp.controller.measured.dataset import TrialEntry
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.jump import jump_from_impulse, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.robot_description import Stance

from .humanoid_feet import SPEED, HeldContactLog
from .observed_criteria import TrialObservation, first_failure, observe
from .runner import run_impact, servoed_plant
from .scene import build_humanoid_scene
from .trial_loop import Ending
from .trial_sources import SCRIPTED, TrialStart

CONTROL_PERIOD = 1e-3
SETTLE = 0.1  # s standing still before the approach
LATENCY = 0.005  # s from the first contact to the stop command
AFTER = 0.4  # s simulated after the impact
SINK = 0.001  # m the soles start into the floor
WINDOW = 0.03  # s: longest first contact read as the impact
SERVO_GAIN = 40.0  # rad/s
SLIP = 0.005  # m of horizontal foot motion counted as a slip
LIFT = 0.005  # m of vertical foot motion counted as a lift
NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall's normal, towards the robot


@dataclass(frozen=True)
class ImpactTrial:
    """What one trial measured and predicted (joint jumps over the joints, rad/s)."""

    stance: str
    speed: float  # commanded hand speed (m/s)
    contact_speed: float  # measured normal approach speed -n.v- (m/s)
    impulse: np.ndarray  # measured wall impulse on the robot (N s, world)
    peak_force: float  # largest normal wall force of a physics step during the first contact (N)
    floor_impulse: np.ndarray  # the floor's impulse on the feet over the same window (N s)
    duration: float  # length of the measurement window (s): the first contact
    measured_jump: np.ndarray  # (nv) generalized-velocity jump, Pinocchio convention
    measured_com_jump: np.ndarray  # (3) m/s
    predicted_jump: dict  # method -> (nv)
    predicted_com_jump: dict  # method -> (3)
    predicted_impulse: dict  # method -> (3)
    errors: dict  # method -> eq. (26) over the joints
    post_com_velocity: np.ndarray  # (3) m/s: the CoM velocity after the first wall contact
    foot_slip: float  # largest horizontal foot displacement (m)
    foot_lift: float  # largest vertical foot displacement (m)
    slide_speed: float  # m/s: largest horizontal speed of a touching sole sphere in the impact window
    criteria: dict  # name -> ``sim.observed_criteria.Observed``, the robot's criteria in their order
    wall_x: float  # m: the wall plane's position
    q_log: np.ndarray  # (steps, nq) Pinocchio configurations at the control rate
    contact_index: int  # the control step of the first wall contact
    source: str = "scripted"  # the command source (``ScriptedCommand.name``, ``QpCommand.name``)
    record: object = None  # what the command source kept of each control step (the QP's ``QpRecord``), or None
    log: TrialLog | None = None  # the trial as a robot logs it (simulation world frame; ``sim.generation``)

    @property
    def feasible(self) -> bool:
        """No criterion failed: no joint beyond its velocity limit, no slip or lift onset, the
        post-impact CoM velocity capturable, no fall."""
        return not self.first_failure

    @property
    def failures(self) -> tuple:
        """Every criterion that failed, in the criteria's order."""
        return tuple(name for name, c in self.criteria.items() if c.failed)

    @property
    def failure_times(self) -> dict:
        """Failed criterion -> s from the first wall contact to its onset (< 0: before it)."""
        return {name: c.onset for name, c in self.criteria.items() if c.failed}

    @property
    def first_failure(self) -> str:
        """The criterion that failed first (``sim.observed_criteria.first_failure``), "" when none."""
        return first_failure(self.criteria)

    @property
    def failure_time(self) -> float:
        """s from the first wall contact to the first failure (nan: none)."""
        return self.failure_times.get(self.first_failure, float("nan"))

    @property
    def fell(self) -> bool:
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
    def max_velocity_ratio(self) -> float:
        """The largest |dq_i| / dq_max_i of the joints after the settling."""
        return self.criteria["joint_velocity"].value

    @property
    def max_velocity_joint(self) -> str:
        """The joint where it occurs."""
        return self.criteria["joint_velocity"].where

    @property
    def commands(self) -> np.ndarray:
        """(steps, joints) the joint velocity commands sent to the servo (rad/s): the log's ``dq_cmd``."""
        return self.log.dq_cmd

    @property
    def trial_id(self) -> str:
        """A file-name-safe id naming the stance, the commanded speed (mm/s) and the command source."""
        return f"{self.stance}_vn{round(self.speed * 1000):d}_{self.source}"

    def dataset_trial(self) -> tuple[TrialEntry, TrialLog]:
        """The manifest's entry of the trial (its files, commanded speed, stance and first wall
        contact) and its log in the dataset's world frame (``sim.generation``: the base's x minus
        the wall's)."""
        name = self.trial_id
        entry = TrialEntry(
            id=name, file=f"{name}.csv", reference_normal_speed=self.speed, force_file=f"{name}_force.csv",
            reference_tangential_velocity=(0.0, 0.0, 0.0), posture=self.stance,
            impact_time=self.contact_index * CONTROL_PERIOD,
        )
        base = self.log.base.copy()
        base[:, 0] -= self.wall_x
        return entry, replace(self.log, base=base)

    def to_json(self, robot: str) -> dict:
        """The trial of the robot named ``robot`` as JSON (``impactqp simulate --robot g1 --json``)."""
        return {
            "robot": robot, "posture": self.stance, "reference_speed": self.speed, "contact_speed": self.contact_speed,
            "impulse": self.impulse.tolist(), "floor_impulse": self.floor_impulse.tolist(),
            "impact_duration": self.duration, "dq_jump": self.measured_jump.tolist(),
            "com_jump": self.measured_com_jump.tolist(),
            "predicted": {m: dv.tolist() for m, dv in self.predicted_jump.items()},
            "predicted_com_jump": {m: c.tolist() for m, c in self.predicted_com_jump.items()},
            "errors": self.errors, "foot_slip": self.foot_slip, "foot_lift": self.foot_lift, "fell": self.fell,
            "max_velocity_ratio": self.max_velocity_ratio, "first_failure": self.first_failure,
            "violated": not self.feasible,
        }

    @property
    def equivalent_duration(self) -> float:
        """The first contact's equivalent duration (s): its normal impulse over its peak force, the
        length of a constant force at the peak that gives the same impulse (the closed form's T)."""
        return float(NORMAL @ self.impulse) / self.peak_force

    @property
    def slipped(self) -> bool:
        """A foot frame moved more than SLIP horizontally (the displacement measure)."""
        return self.foot_slip > SLIP

    @property
    def lifted(self) -> bool:
        """A foot frame moved more than LIFT vertically (the displacement measure)."""
        return self.foot_lift > LIFT


def run_impact_trial(robot: RobotModel, stance: Stance, speed: float, *, gain: float = SERVO_GAIN,
                     armature=None, q0: np.ndarray | None = None, gap: float | None = None, source=SCRIPTED) -> ImpactTrial:
    """Simulate one trial (module docstring; ``sim.runner.run_impact``) and compare the jump with
    the predictors; ``gap`` (m) is the start distance of the contact point from the wall (None:
    the source's), ``armature`` the plant's rotor inertia (``sim.scene.plant_armature``: None for
    the G1's actuators), ``source`` the command source (``sim.trial_sources``: ``SCRIPTED``, or
    ``QpCommand``: the whole-body QP)."""
    q0 = stance_posture(robot, stance) if q0 is None else q0
    gap = source.gap if gap is None else gap
    contact0 = robot.frame_placements(q0)[robot.model.frames[robot.contact_frame_id].name].translation
    scene = build_humanoid_scene(robot, wall_x=float(contact0[0]) + gap, armature=armature)
    plant = servoed_plant(scene, robot, CONTROL_PERIOD, gain)
    contact = robot.terms(q0).contact_point
    wall = Surface(np.array([scene.wall_x, contact[1], contact[2]]), NORMAL.copy())
    ending = Ending(
        int(round((SETTLE + source.approach_time(gap, speed)) / CONTROL_PERIOD)), after=int(round(AFTER / CONTROL_PERIOD)),
        stop_after=int(round(LATENCY / CONTROL_PERIOD)), hold=source.holds_at_stop,
    )
    run = run_impact(plant, source, TrialStart(robot, q0, np.zeros(robot.nv), wall, speed, settle=SETTLE, sink=SINK,
                                               control_period=CONTROL_PERIOD), ending)
    record = run.record
    first = record.first_contact
    if first is None:
        raise RuntimeError(f"the hand never reached the wall (stance {stance.name}, {speed} m/s, {source.name} command)")
    walls = record.force.reshape(len(record.t), plant.substeps, 3)
    forces, peaks = (walls * scene.timestep).sum(axis=1), np.maximum((walls @ NORMAL).max(axis=1), 0.0)
    trial = _evaluate(robot, stance, speed, _Contact(forces, peaks, first), run.log, record.held, scene.wall_x)
    return replace(trial, source=source.name, record=run.driver.record, log=run.log)


@dataclass(frozen=True)
class _Contact:
    """The wall per control step: its impulse on the robot (steps, 3), the sum of its physics
    steps', and its largest normal force of a physics step (steps,) (N, 0 without one); the
    control step of the first wall contact."""

    forces: np.ndarray
    peaks: np.ndarray
    first: int

    @property
    def last(self) -> int:
        """The last control step of the first contiguous contact (at most WINDOW s long)."""
        last, window = self.first, int(round(WINDOW / CONTROL_PERIOD))
        while last + 1 < min(len(self.forces), self.first + window) and np.any(self.forces[last + 1] != 0.0):
            last += 1
        return last


def _measured_jumps(robot, o: TrialObservation, contact: _Contact, terms) -> dict:
    """The measured and predicted jumps over the first wall contact (module docstring); ``terms``
    the model terms before it."""
    first, last = o.first, o.last
    q_pre, v_pre = o.state(first)
    q_post, v_post = o.state(o.post)
    impulse = o.impulse
    post_terms = robot.terms(q_post)
    v_minus = terms.J @ v_pre
    measured = v_post - v_pre
    joints = slice(robot.base_nv, None)
    predicted, com, impulses = {}, {}, {}
    for method in METHODS:
        jump = predict(terms, method, NORMAL, v_minus)
        predicted[method], com[method], impulses[method] = jump.dq_jump, jump.com_jump, jump.impulse
    predicted["momentum"] = jump_from_impulse(terms, impulse)
    com["momentum"] = terms.Jcom @ predicted["momentum"]
    impulses["momentum"] = impulse
    post_com_velocity = post_terms.Jcom @ v_post
    return dict(
        contact_speed=float(-NORMAL @ v_minus), impulse=impulse, peak_force=float(contact.peaks[first:last + 1].max()),
        floor_impulse=o.held.floor[first:last + 1].sum(axis=0), duration=o.duration,
        measured_jump=measured, measured_com_jump=post_com_velocity - terms.Jcom @ v_pre,
        predicted_jump=predicted, predicted_com_jump=com, predicted_impulse=impulses,
        errors={m: float(np.mean(np.abs(dv[joints] - measured[joints]))) for m, dv in predicted.items()},
        post_com_velocity=post_com_velocity,
    )


def _evaluate(robot, stance, speed, contact: _Contact, log: TrialLog, held: HeldContactLog, wall_x) -> ImpactTrial:
    """Measured and predicted jumps and the observed criteria of a simulated trial (module docstring)."""
    first, last = contact.first, contact.last
    start = int(round(SETTLE / CONTROL_PERIOD))
    watched = np.arange(len(log)) >= start
    terms = robot.terms(np.concatenate([log.base[first, :robot.base_nq], log.q[first]]))
    observation = TrialObservation(
        robot, log, watched, first, last, contact.forces[first:last + 1].sum(axis=0),
        (last + 1 - first) * CONTROL_PERIOD, terms.J, CONTROL_PERIOD, held,
    )
    jumps = _measured_jumps(robot, observation, contact, terms)
    impact = held.soles[observation.impact_window()]
    loaded = observation.loaded_before()
    moved = held.feet[start:] - held.feet[start]
    return ImpactTrial(
        stance=stance.name, speed=speed, **jumps,
        foot_slip=float(np.linalg.norm(moved[..., :2], axis=-1).max()),
        foot_lift=float(np.abs(moved[..., 2]).max()),
        slide_speed=float(impact[:, loaded, SPEED].max()), criteria=observe(observation),
        wall_x=wall_x, q_log=np.column_stack([log.base[:, :robot.base_nq], log.q]), contact_index=first,
    )
