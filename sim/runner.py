"""The fixed-base arm's closed-loop trials: a 1 kHz command source drives the MuJoCo arm through a
joint servo, in the one trial loop of every robot (``sim.trial_loop``: state, command, servo
torque held over the period, physics substeps with the wall's contact force logged).

The arm's command sources: the QP controller, a :class:`CartesianApproachCommand` or a
:class:`CommandReplay` of a logged sequence (``sim.trial_loop.CommandSource``); :func:`run_trial`
runs one for a given duration from a given state, :func:`run_approach` one approach-and-impact
trial (:class:`TrialSpec`).

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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from impactqp.constraints import jump_model_names
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.max_speed import DEFAULT_IMPACT_DURATION
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError, approach_speed, finite_vector
from impactqp.controller.model.validation import impact_duration as check_impact_duration
from impactqp.controller.model.validation import restitution as check_restitution
from impactqp.controller.model.validation import tangential_velocity as tangential_velocity_along

from .scene import Scene
from .trial_loop import FEEDBACK, CommandSource, Ending, ServoedPlant, VelocityCommand, run_loop

# A diverging simulation is detected from MuJoCo's warning counters and raised as
# SimulationUnstableError (_check_stable); the C library must not also print each warning.
mujoco.set_mju_user_warning(lambda message: None)

DEFAULT_CONTROL_PERIOD = 1e-3
OBSERVATION_WINDOW = 0.05
"""s after the contact start in which a trial's velocities are observed (``docs/max-speed.md``)."""
LAG_ALLOWANCE = 3.0


UNSTABLE_VELOCITY_FACTOR = 5.0
"""A trial whose |dq| exceeds this many times the velocity limits has diverged: no impact of a
real Panda comes near it, and the data would be garbage."""


class SimulationUnstableError(BadInputError):
    """The simulated state diverged (non-finite, or |dq| far above the limits): the plant or the
    request lies outside what the model simulates faithfully. Such a trial is never data."""


class CartesianApproachCommand:
    """Move the contact point at a constant world velocity with the orientation held.

    dq_cmd = J6+ [v_ref; 0], v_ref = -v_n n + v_t, with J6 the 6x7 (linear; angular) Jacobian of
    the contact frame and J6+ its Moore-Penrose pseudo-inverse (minimum joint-velocity norm). A
    purely kinematic, open-loop-in-task-space approach: no drift correction, which is harmless
    over the few centimetres of an impact trial. It never stops: after the impact it keeps
    commanding motion into the wall (the servo then presses with a slowly growing force).
    """

    def __init__(
        self,
        robot: PandaModel,
        surface: Surface,
        normal_speed: float,
        tangential_velocity: np.ndarray | None = None,
    ):
        approach_speed(normal_speed, "normal_speed")
        v_t = np.zeros(3) if tangential_velocity is None else tangential_velocity_along(tangential_velocity, surface.normal)
        self.robot = robot
        self.twist = np.concatenate([-normal_speed * surface.normal + v_t, np.zeros(3)])

    def step(self, q: np.ndarray, dq: np.ndarray) -> VelocityCommand:
        J6 = self.robot.contact_jacobian6(q)
        return VelocityCommand(np.linalg.lstsq(J6, self.twist, rcond=None)[0])


class CommandReplay:
    """Replay a logged sequence of joint-velocity commands of ``joints`` joints, one row per
    control step."""

    def __init__(self, dq_cmd: np.ndarray, joints: int):
        dq_cmd = np.asarray(dq_cmd, dtype=float)
        if dq_cmd.ndim != 2 or dq_cmd.shape[1] != joints or len(dq_cmd) == 0:
            raise BadInputError(f"a command replay needs an (N, {joints}) array, got shape {dq_cmd.shape}")
        if not np.all(np.isfinite(dq_cmd)):
            raise BadInputError("the replayed commands contain a non-finite value")
        self.dq_cmd = dq_cmd
        self.index = 0

    def __len__(self) -> int:
        return len(self.dq_cmd)

    def step(self, q: np.ndarray, dq: np.ndarray) -> VelocityCommand:
        if self.index >= len(self.dq_cmd):
            raise IndexError(f"the command replay holds only {len(self.dq_cmd)} control steps")
        command = VelocityCommand(self.dq_cmd[self.index])
        self.index += 1
        return command


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
    """Simulate ``duration`` seconds of closed-loop control from the state (q0, dq0).

    The servo's reference starts at the state, or at ``servo_reference`` = (q_ref, dq_ref) to
    resume a trial in the middle (see :func:`servo_reference_from_commands`).
    The servo gain is the scene's ``plant.servo_gain``; ``control_period`` must be a whole
    number of physics timesteps.
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
    plant.reset(q0, dq0, servo_reference)
    record = run_loop(plant, source, Ending(steps))
    _check_stable(scene, record.t, record.dq)
    return TrialLog(record.t, record.q, record.dq, record.tau, record.dq_cmd, record.force_t, record.force,
                    record.wall_time)


def _check_stable(scene: Scene, t: np.ndarray, dq: np.ndarray) -> None:
    """Raise :class:`SimulationUnstableError` when the trial diverged: a non-finite or huge joint
    velocity, or MuJoCo's own reset after a bad acceleration."""
    limit = UNSTABLE_VELOCITY_FACTOR * scene.robot.dq_max
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
    scene: Scene,
    robot: PandaModel,
    spec: TrialSpec,
    source: Callable[[np.ndarray, np.ndarray], CommandSource] | None = None,
    duration: float | None = None,
) -> TrialLog:
    """The one approach runner: the trial ``spec`` on the scene's surface.

    Starts ``spec.start_distance`` in front of the surface (``inverse_kinematics.approach_start``
    from ``spec.q_contact``), at rest or moving at the reference velocity of
    :class:`CartesianApproachCommand`. The command source is that Cartesian command, or
    ``source(q0, dq0)`` (the QP controller of a scenario trial). The trial lasts ``duration``; by
    default the nominal time to contact with a ``LAG_ALLOWANCE`` margin (a plant that lags behind
    the command, e.g. joint damping against a soft servo, touches later). It ends
    ``spec.after_contact`` seconds after the first contact; without any contact it ends at the
    duration.
    """
    q0 = approach_start(robot, spec.q_contact, scene.surface, spec.start_distance)
    approach = CartesianApproachCommand(robot, scene.surface, spec.normal_speed, spec.tangential_velocity)
    dq0 = np.zeros(robot.nv) if spec.start_at_rest else approach.step(q0, np.zeros(robot.nv)).dq_cmd
    command = approach if source is None else source(q0, dq0)
    if duration is None:
        duration = LAG_ALLOWANCE * spec.start_distance / spec.normal_speed + spec.after_contact
    log = run_trial(scene, command, q0, dq0, duration)
    touching = np.flatnonzero(np.linalg.norm(log.force, axis=1) > 0.0)
    if touching.size == 0:
        return log
    return log.truncated(log.force_t[touching[0]] + spec.after_contact)
