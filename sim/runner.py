"""The one trial runner of every robot: a command source (``sim.trial_sources``: the arm's
Cartesian approach or replay, the standing robot's scripted arm, the QP of any robot) drives the
MuJoCo plant through the joint servo, in the one trial loop (``sim.trial_loop``: state, command,
servo torque held over the period, physics substeps with the wall's contact force logged), and
the trial is logged as a robot logs it (``TrialLog``; a floating base's state in its base columns).

:func:`run_impact` runs one source from a :class:`~sim.trial_sources.TrialStart` until an
``Ending``, on the plant of :func:`servoed_plant` (a robot with held contacts stands on them);
:func:`run_trial` runs a fixed-base arm's command source for a given duration from a given state,
:func:`run_approach` an arm's approach-and-impact trial (:class:`TrialSpec`), and
:func:`run_impact_trial` a standing robot's (below); every trial's result is a
``sim.trial_result.TrialResult``.

Servo (the arm's kinematic control, a plant property): ``sim.servo.ComputedTorqueServo``, a
computed-torque joint PD with acceleration feed-forward that tracks the commanded velocity,

    tau_k = M(q_k) (ddq_ref_k + omega^2 (q_ref_k - q_k) + 2 omega (dq_ref_k - dq_k)) + h(q_k, dq_k).

Feed-forward makes the joints follow smooth commands exactly (kinematic control) whatever the
gain; the feedback, critically damped with bandwidth omega = ``PlantParameters.servo_gain``,
only acts on disturbances such as the impact. Its default, 5 rad/s, is far below the impact's
(contact time constant 7 ms), so the plain plant jumps like the rigid-body model of the classical
prediction (docs/simulation.md): the feedback reacts to the jump itself with an acceleration
2 omega ddq, which over an impact of duration delta changes the jump by up to 2 omega delta
(15 % for 15 ms at 5 rad/s; what it does on the named postures: docs/results.md). M includes
the armature and h = Coriolis, centrifugal and gravity terms (``qfrc_bias``). ``tau`` in the log
is this torque, the "measured joint torque" of a trial.

A standing robot's trial (:func:`run_impact_trial`, docs/floating-base.md): the robot (the G1)
starts at rest in a stance (``controller.model.humanoid_stance``), the wall the source's ``gap``
beyond its contact point. It stands still for :data:`SETTLE` s, then the right arm (shoulder,
elbow, wrist: its description's ``contact.joints``) is driven so that the hand moves along +x at
``speed``: dq_arm = J_arm^+ v* (J_arm the arm joints' block of the contact Jacobian), reached by a
20 ms velocity ramp; every other joint is commanded at rest. At the first wall contact (plus a
:data:`LATENCY` detection latency) the arm stops: the servo's reference is re-anchored at the
measured joint positions, at rest (``ComputedTorqueServo.hold``), and the command is zero from
then on; the trial goes on for :data:`AFTER` s to see whether the robot stands. Why re-anchor
rather than only command zero velocity: the wall has already stopped the hand, but the reference
still moves at the approach speed, so a zero command asks the servo for the reference's whole
deceleration -dq_ref/dt in one control step; the waist and shoulder torques saturate and the
reaction jolts the feet (what that stop did: docs/results.md, "G1: servo and stop"). Re-anchored,
the servo only damps the joints' post-impact velocities. That is the default command source
(``sim.trial_sources.SCRIPTED``); ``source`` chooses another one, e.g. the whole-body QP
(``sim.trial_sources.QpCommand``): a source (``TrialSource``) gives its start gap, the time it may
take to reach the wall (``approach_time``), per trial a driver, the command source of the one
trial loop (``sim.trial_loop``: ``step(q, v)`` returns the joints' velocity command, ``stop()``
tells it that LATENCY has passed since the first contact), and whether the servo re-anchors its
reference at the stop (``holds_at_stop``).

Its servo (``sim.servo.ComputedTorqueServo``, standing on the feet through
``sim.servo.StandingSupport``): a joint-space computed-torque PD with acceleration feed-forward on
the joints, tau = M_f (ddq_ref + w^2 e + 2 w de) + h_j - tau_feet, with M_f the joints' inertia
with the base floating and tau_feet the joint torques of the least-norm foot wrenches that carry
the robot's weight in the measured configuration (every control step: the weight's share between
the feet and their moments follow the posture, which the whole-body QP leans; wrenches of the
start stance would leave the ankles a steady tracking error), gain :data:`SERVO_GAIN`, and at the
ankles the PD of the body's pendulum about them (``sim.servo``, "The ankles carry the body"). The torque
each joint gets is clipped at its URDF effort limit (5-139 N m). Its plant: MuJoCo's G1 with the
actuators' reflected rotor inertias by default (``armature``: ``sim.humanoid_scene.plant_armature``; 0 for
the link-only plant). The servo's M_f includes them (MuJoCo's M does); the predictors do not (they
keep the URDF model). Its measurement, predictions and failure criteria:
``sim.trial_result.held_contact_result``; its log (``TrialResult.log``) holds the trial as a robot
logs it, the base state among it (``sim.generation`` writes it as a dataset).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from impactqp.constraints import jump_model_names
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.max_speed import DEFAULT_IMPACT_DURATION
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import Stance
from impactqp.controller.model.validation import BadInputError, approach_speed, finite_vector
from impactqp.controller.model.validation import impact_duration as check_impact_duration
from impactqp.controller.model.validation import restitution as check_restitution

from .humanoid_scene import build_humanoid_scene
from .scene import WALL_FRICTION, MujocoScene, Scene
from .servo import StandingSupport
from .trial_loop import FEEDBACK, CommandSource, Ending, LoopRecord, ServoedPlant, run_loop
from .trial_result import TrialResult, WallContact, held_contact_result
from .trial_sources import CARTESIAN, SCRIPTED, CartesianApproachCommand, TrialSource, TrialStart

# A diverging simulation is detected from MuJoCo's warning counters and raised as
# SimulationUnstableError (_check_stable); the C library must not also print each warning.
mujoco.set_mju_user_warning(lambda message: None)

DEFAULT_CONTROL_PERIOD = 1e-3
OBSERVATION_WINDOW = 0.05
"""s after the contact start in which a trial's velocities are observed (``docs/max-speed.md``)."""
LAG_ALLOWANCE = 3.0

# a standing robot's trial (module docstring)
SETTLE = 0.1  # s standing still before the approach
LATENCY = 0.005  # s from the first contact to the stop command
AFTER = 0.4  # s simulated after the impact
SINK = 0.001  # m the soles start into the floor
SERVO_GAIN = 40.0  # rad/s
NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall's normal, towards the robot


UNSTABLE_VELOCITY_FACTOR = 5.0
"""A trial whose |dq| exceeds this many times the velocity limits has diverged: no impact of a
real Panda comes near it, and the data would be garbage."""


class SimulationUnstableError(BadInputError):
    """The simulated state diverged (non-finite, or |dq| far above the limits): the plant or the
    request lies outside what the model simulates faithfully. Such a trial is never data."""


@dataclass(frozen=True)
class TrialSpec:
    """One approach-and-impact trial: where it hits, how fast, and how it is controlled.

    The trial starts ``start_distance`` in front of the surface at the posture that
    ``controller.model.inverse_kinematics.approach_start`` finds for ``q_contact``, at rest
    (``start_at_rest``) or already moving at the reference velocity, and lasts until ``after_contact`` seconds after the first contact.
    ``jump_model``: the jump-aware constraints of the controller ('crb', 'gm', 'classical',
    'classical_normal', 'robust') or None to switch them off. ``restitution`` and
    ``impact_duration`` are the controller's c_r and delta_t (and c_r of the predictions).
    ``after_contact``: simulated time after the nominal contact (must hold the 50 ms window).
    A robot with held contacts (``scenarios.trial.TrialRunner``) takes the stance ``posture`` of
    its description at its posture ``q_contact`` and the hand speed ``normal_speed``; its wall,
    start, stop and ending are its standing trial's (:func:`run_impact_trial`), the other fields
    unused.
    """

    posture: str
    q_contact: np.ndarray
    normal_speed: float
    tangential_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    jump_model: str | None = None
    restitution: float = 0.0
    impact_duration: float = DEFAULT_IMPACT_DURATION
    start_at_rest: bool = False
    start_distance: float = 0.02
    after_contact: float = 0.06
    feedback: str = "commanded"

    def __post_init__(self):
        approach_speed(self.normal_speed)
        tangential = finite_vector(self.tangential_velocity, 3, "the tangential velocity")
        object.__setattr__(self, "tangential_velocity", tangential)
        object.__setattr__(self, "q_contact", np.asarray(self.q_contact, dtype=float))
        if self.jump_model is not None:
            jump_model_names(self.jump_model)
        check_restitution(self.restitution)
        check_impact_duration(self.impact_duration)
        if self.after_contact < OBSERVATION_WINDOW:
            raise BadInputError(f"after_contact must be at least {OBSERVATION_WINDOW} s")
        if self.feedback not in FEEDBACK:
            raise BadInputError(f"feedback must be one of {', '.join(FEEDBACK)}, got {self.feedback!r}")

    @property
    def trial_id(self) -> str:
        """A file-name-safe id naming the posture, the speeds (mm/s) and the jump constraints."""
        text = f"{self.posture}_vn{_mm(self.normal_speed)}"
        if np.any(self.tangential_velocity != 0.0):
            text += "_vt" + "_".join(_mm(v) for v in self.tangential_velocity)
        return text + f"_{self.jump_model or 'free'}"


def _mm(value: float) -> str:
    """A speed in mm/s as an integer string, 'm' for a minus sign."""
    return f"{round(value * 1000):d}".replace("-", "m")


@dataclass(frozen=True)
class TrialRun:
    """What one trial of :func:`run_impact` or :func:`run_source` recorded: the trial as a robot
    logs it (``TrialLog``; base columns only for a floating base), the loop's record (the held
    contacts' log among it) and the driver that commanded it (its ``record``, its controller)."""

    log: TrialLog
    record: LoopRecord
    driver: CommandSource


def servoed_plant(scene: MujocoScene, robot: RobotModel, control_period: float = DEFAULT_CONTROL_PERIOD,
                  gain: float | None = None) -> ServoedPlant:
    """The scene's plant under the joint servo of gain ``gain`` (None: the plant's); a robot with
    held contacts stands on them (``sim.servo.StandingSupport``)."""
    standing = StandingSupport(robot, scene.base_nq, scene.base_nv) if robot.description.held_contacts else None
    return ServoedPlant(scene, control_period, gain=gain, standing=standing)


def run_source(plant: ServoedPlant, driver: CommandSource, ending: Ending, start: tuple, dq_max: np.ndarray,
               servo_reference: tuple[np.ndarray, np.ndarray] | None = None) -> TrialRun:
    """The trial loop of ``driver`` from the Pinocchio state ``start`` = (q0, dq0) (dq0 None: at
    rest) until ``ending``, checked stable against the joints' velocity limits ``dq_max``; the
    servo's reference starts at the state, or at ``servo_reference`` = (q_ref, dq_ref) to resume a
    trial in the middle (see :func:`servo_reference_from_commands`)."""
    plant.reset(*start, servo_reference)
    record = run_loop(plant, driver, ending)
    scene = plant.scene
    _check_stable(scene, record.t, record.dq[:, scene.base_nv:], dq_max)
    base = (np.column_stack([record.q[:, :scene.base_nq], record.dq[:, :scene.base_nv]]) if scene.base_nq
            else np.zeros((0, 13)))
    log = TrialLog(record.t, record.q[:, scene.base_nq:], record.dq[:, scene.base_nv:], record.tau, record.dq_cmd,
                   record.force_t, record.force, record.wall_time, base=base)
    return TrialRun(log, record, driver)


def run_impact(plant: ServoedPlant, source: TrialSource, start: TrialStart, ending: Ending) -> TrialRun:
    """One impact trial of any robot: ``source`` started at ``start`` drives the plant from the
    start state until ``ending``."""
    return run_source(plant, source.start(start), ending, (start.plant_start(), start.dq0), start.robot.dq_max)


def run_trial(
    scene: Scene,
    source: CommandSource,
    q0: np.ndarray,
    dq0: np.ndarray,
    duration: float,
    *,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    servo_reference: tuple[np.ndarray, np.ndarray] | None = None,
) -> TrialLog:
    """Simulate ``duration`` seconds of a fixed-base arm's closed-loop control by ``source`` from
    the state (q0, dq0) (:func:`run_source`). The servo gain is the scene's ``plant.servo_gain``;
    ``control_period`` must be a whole number of physics timesteps.
    """
    plant = ServoedPlant(scene, control_period)
    steps = int(round(duration / control_period))
    if steps < 1:
        raise BadInputError(f"duration {duration} s is shorter than one control period")
    q0 = np.asarray(q0, dtype=float)
    dq0 = np.asarray(dq0, dtype=float)
    nq, nv = scene.model.nq, scene.model.nv
    if q0.shape != (nq,) or dq0.shape != (nv,):
        raise BadInputError(f"the start state needs {nq} joint positions and {nv} velocities")
    return run_source(plant, source, Ending(steps), (q0, dq0), scene.robot.dq_max, servo_reference).log


def _check_stable(scene: MujocoScene, t: np.ndarray, dq: np.ndarray, dq_max: np.ndarray) -> None:
    """Raise :class:`SimulationUnstableError` when the trial diverged: a non-finite or huge joint
    velocity, or MuJoCo's own reset after a bad acceleration."""
    limit = UNSTABLE_VELOCITY_FACTOR * dq_max
    bad = ~np.all(np.isfinite(dq) & (np.abs(dq) <= limit), axis=1)
    resets = scene.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
    if np.any(bad) or resets:
        k = int(np.flatnonzero(bad)[0]) if np.any(bad) else len(t) - 1
        peak = float(np.max(np.abs(dq[k]))) if np.all(np.isfinite(dq[k])) else float("inf")
        raise SimulationUnstableError(
            f"the simulation became unstable at t = {t[k]:.3f} s (|dq| = {peak:.3g} rad/s, more than "
            f"{UNSTABLE_VELOCITY_FACTOR:g} times the limits, or a MuJoCo reset): the plant or the requested "
            "motion lies outside what the model simulates; nothing was written"
        )


def servo_reference_from_commands(
    q_start: np.ndarray, dq_start: np.ndarray, dq_cmd: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """The servo reference after the commands ``dq_cmd`` (one row per period) from a trial start.

    The servo integrates its commands (module docstring): q_ref_{k+1} = q_ref_k +
    dt (dq_ref_k + dq_cmd_k) / 2 and dq_ref_{k+1} = dq_cmd_k, from (q_ref, dq_ref)(0) equal to the
    start state. A log's commands therefore give the reference at any later sample.
    """
    dq_cmd = np.asarray(dq_cmd, dtype=float)
    if len(dq_cmd) == 0:
        return np.array(q_start, dtype=float), np.array(dq_start, dtype=float)
    previous = np.vstack([dq_start, dq_cmd[:-1]])
    q_ref = np.asarray(q_start, dtype=float) + 0.5 * dt * np.sum(previous + dq_cmd, axis=0)
    return q_ref, dq_cmd[-1].copy()


def run_approach(
    scene: Scene, robot: RobotModel, spec: TrialSpec, source: TrialSource = CARTESIAN, duration: float | None = None
) -> TrialRun:
    """A fixed-base arm's approach-and-impact trial ``spec`` on the scene's surface (:func:`run_impact`).

    Starts ``spec.start_distance`` in front of the surface (``inverse_kinematics.approach_start``
    from ``spec.q_contact``), at rest or moving at the reference velocity of
    ``CartesianApproachCommand``. The command source is ``source`` (default: that Cartesian
    command; the QP controller of a scenario trial is ``QpCommand``). The trial lasts ``duration``;
    by default the nominal time to contact with a ``LAG_ALLOWANCE`` margin (a plant that lags
    behind the command, e.g. joint damping against a soft servo, touches later). Its log ends
    ``spec.after_contact`` seconds after the first contact; without any contact it ends at the
    duration.
    """
    q0 = approach_start(robot, spec.q_contact, scene.surface, spec.start_distance)
    approach = CartesianApproachCommand(robot, scene.surface, spec.normal_speed, spec.tangential_velocity)
    dq0 = np.zeros(robot.nv) if spec.start_at_rest else approach.step(q0, np.zeros(robot.nv)).dq_cmd
    if duration is None:
        duration = LAG_ALLOWANCE * spec.start_distance / spec.normal_speed + spec.after_contact
    steps = int(round(duration / DEFAULT_CONTROL_PERIOD))
    if steps < 1:
        raise BadInputError(f"duration {duration} s is shorter than one control period")
    start = TrialStart(robot, q0, dq0, scene.surface, spec.normal_speed, spec.tangential_velocity)
    run = run_impact(servoed_plant(scene, robot), source, start, Ending(steps))
    log = run.log
    touching = np.flatnonzero(np.linalg.norm(log.force, axis=1) > 0.0)
    if touching.size == 0:
        return run
    return replace(run, log=log.truncated(log.force_t[touching[0]] + spec.after_contact))


class WallNotReachedError(RuntimeError):
    """A standing trial whose hand never touched the wall; ``run``: what it recorded
    (``TrialRun``: the loop's record and the driver's, a QP's statuses among it)."""

    def __init__(self, message: str, run: TrialRun):
        super().__init__(message)
        self.run = run


def standing_wall_friction(source: TrialSource) -> float:
    """The standing scene's wall friction for ``source``: the mu its QP's friction rows were given
    (the wall the rows are for, as ``simulate --friction`` sets an arm's wall; 0: no rows and a
    frictionless wall), else the paper's ``WALL_FRICTION``."""
    friction = getattr(source, "friction", None)
    return WALL_FRICTION if friction is None else friction


def run_impact_trial(robot: RobotModel, stance: Stance, speed: float, *, gain: float = SERVO_GAIN,
                     armature=None, q0: np.ndarray | None = None, gap: float | None = None,
                     source: TrialSource = SCRIPTED) -> TrialResult:
    """Simulate one trial of a standing robot (module docstring; :func:`run_impact`) and compare
    the jump with the predictors (``sim.trial_result.held_contact_result``); ``gap`` (m) is the
    start distance of the contact point from the wall at q0 (None: the source's start posture and
    gap from q0, ``start_posture``: the scripted arm's 2 cm, the QP's run-up), ``armature`` the
    plant's rotor inertia (``sim.humanoid_scene.plant_armature``: None for the G1's actuators), ``source``
    the command source (``sim.trial_sources``: ``SCRIPTED``, or ``QpCommand``: the whole-body QP)."""
    dt = DEFAULT_CONTROL_PERIOD
    q0 = stance_posture(robot, stance) if q0 is None else q0
    contact_posture = q0
    if gap is None:
        q0, gap = source.start_posture(robot, q0, NORMAL, speed)
    contact0 = robot.frame_placements(q0)[robot.model.frames[robot.contact_frame_id].name].translation
    scene = build_humanoid_scene(robot, wall_x=float(contact0[0]) + gap, armature=armature, stance=stance,
                                 wall_friction=standing_wall_friction(source))
    plant = servoed_plant(scene, robot, dt, gain)
    contact = robot.terms(q0).contact_point
    wall = Surface(np.array([scene.wall_x, contact[1], contact[2]]), NORMAL.copy())
    ending = Ending(
        int(round((SETTLE + source.approach_time(gap, speed)) / dt)), after=int(round(AFTER / dt)),
        stop_after=int(round(LATENCY / dt)), hold=source.holds_at_stop,
    )
    start = TrialStart(robot, q0, np.zeros(robot.nv), wall, speed, settle=SETTLE, sink=SINK, control_period=dt,
                       contact_posture=contact_posture)
    run = run_impact(plant, source, start, ending)
    touched = WallContact.of(run.record, plant, start)
    if touched is None:
        raise WallNotReachedError(
            f"the hand never reached the wall (stance {stance.name}, {speed} m/s, {source.name} command)", run
        )
    return held_contact_result(stance.name, start, touched, run, source.name)
