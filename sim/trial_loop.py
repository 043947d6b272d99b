"""The one closed-loop trial of every robot: a command source drives the MuJoCo plant through the
joint servo, one control period dt (1 ms) at a time.

At control step k (t_k = k dt):

1. the state is read: (q_k, dq_k) the joints' for a fixed base; for a floating base Pinocchio's
   (q, v), the base's coordinates first (``sim.scene.to_pinocchio``), and, with held contacts, the
   held contacts' frame positions (:class:`~sim.humanoid_feet.HeldContactLog`);
2. the command source (:class:`CommandSource`) maps it to ``dq_cmd``, the joints' commanded
   velocity (the arm's Cartesian approach, a replay or the QP; the standing robot's scripted arm
   or whole-body QP);
3. the servo (``sim.servo.ComputedTorqueServo``, with ``StandingSupport`` for a floating base held
   by its contacts; an arm's ``JointImpedanceServo`` when its plant sets ``servo_stiffness``) turns it into joint torques, held constant over the period (zero-order hold);
4. MuJoCo advances ``dt / timestep`` substeps; the wall's contact force on the robot is logged at
   every substep (zero, without a per-substep Python loop, while a fixed-base arm's tool is too
   far from the wall to touch it within the period even at 5 m/s) and, with held contacts, the
   floor's impulse and the soles' states.

The trial lasts ``Ending.steps`` control steps; a floating-base trial's ending is set at the first
wall contact k_c: it ends ``after`` steps later and, ``stop_after`` steps after k_c, its source is
told to stop (:class:`StoppingSource`) and, with ``hold``, the servo re-anchors its reference at
the measured joint positions, at rest (``ComputedTorqueServo.hold``).

The two plants differ in one point of the per-period order: the fixed-base arm's servo reads M and
h of the current state (``mj_step1`` before the torque), the standing robot's those that MuJoCo
left from the previous physics step (its servo torque before the period's first ``mj_step``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np
import pinocchio as pin
from numba import njit

from impactqp.controller.model.validation import BadInputError, all_finite

from .contact_force import ContactForces
from .humanoid_feet import HeldContactLog
from .scene import MujocoScene, to_pinocchio
from .servo import ComputedTorqueServo, JointImpedanceServo, StandingSupport

CLEARANCE_SPEED = 5.0


@njit(cache=True)
def any_nonzero(rows) -> bool:
    """Whether any entry of the 2-D array ``rows`` is not zero (``rows.any()``, compiled)."""
    for i in range(rows.shape[0]):
        for j in range(rows.shape[1]):
            if rows[i, j] != 0.0:
                return True
    return False


class JointVelocityCommand(Protocol):
    dq_cmd: np.ndarray


class CommandSource(Protocol):
    """Anything that maps the measured state to a joint-velocity command, once per period."""

    def step(self, q: np.ndarray, dq: np.ndarray) -> JointVelocityCommand: ...


class StoppingSource(CommandSource, Protocol):
    """A command source that is told when the trial stops its approach (module docstring)."""

    def stop(self) -> None: ...


@dataclass(frozen=True)
class VelocityCommand:
    """A plain joint-velocity command (the ``dq_cmd`` of the scripted sources)."""

    dq_cmd: np.ndarray


FEEDBACK = ("commanded", "measured", "blended")
BLEND_CROSSOVER = 10.0
"""rad/s: the crossover frequency omega_c of the blended state (:class:`ControllerSource`)."""


class ControllerSource:
    """A controller (``step(q, dq) -> Command``) as a command source, given as its state (the first
    step always gets the measured state):

    - ``"commanded"``: its own previous command (q_cmd, dq_cmd) (a kinematic-controlled robot's
      controller follows its own smooth command trajectory, docs/simulation.md); it never sees
      the body sway;
    - ``"measured"``: the measured state; through the servo's acceleration feed-forward
      (dq_cmd_k - dq_cmd_{k-1}) / dt this loop feeds back the tracking error e = v_meas - v_cmd
      with the gain 1 / dt (1000 /s), far above the servo's own damping 2 omega (80 /s on the G1),
      and runs away (docs/whole-body-qp.md, "The state the QP is given");
    - ``"blended"``: a complementary blend of the two, the command's integration corrected
      towards the measurement,

          x_k = x_cmd,k-1 (+) alpha (x_meas,k (-) x_cmd,k-1),     alpha = omega_c dt,

      ((+), (-): Pinocchio's integrate and difference, a floating base's pose on its manifold): a
      first-order filter that follows the command above the crossover omega_c and the measurement
      below it (a constant offset decays as (1 - alpha)^k, time constant 1 / omega_c). The tracking
      error reaches the servo's feed-forward with the gain omega_c instead of 1 / dt:
      omega_c = ``crossover`` (:data:`BLEND_CROSSOVER`, 10 rad/s) stays below the servo's damping.

    The source's command is the actuated joints' part of the controller's (a floating base's
    velocities come first). ``last`` is the controller's last Command."""

    def __init__(self, controller, feedback: str, crossover: float = BLEND_CROSSOVER):
        if feedback not in FEEDBACK:
            raise BadInputError(f"unknown feedback {feedback!r}; choose from {', '.join(FEEDBACK)}")
        self.controller, self.feedback = controller, feedback
        self.joints = slice(controller.robot.base_nv, None)
        self.blend = crossover * controller.dt
        self.last = None

    def state(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The state the controller is given (class docstring) from the measured state (q, dq)."""
        last = self.last
        if last is None or self.feedback == "measured":
            return q, dq
        if self.feedback == "commanded":
            return last.q_cmd, last.dq_cmd
        model, alpha = self.controller.robot.model, self.blend
        q_blend = pin.integrate(model, last.q_cmd, alpha * pin.difference(model, last.q_cmd, q))
        return q_blend, last.dq_cmd + alpha * (dq - last.dq_cmd)

    def step(self, q: np.ndarray, dq: np.ndarray) -> VelocityCommand:
        self.last = self.controller.step(*self.state(q, dq))
        return VelocityCommand(self.last.dq_cmd[self.joints])


class ServoedPlant:
    """The scene's plant under the joint servo, advanced one control period per command (steps 3
    and 4 of the module docstring); the fixed-base arm's (``standing`` None, the servo gain its
    plant's) or a floating base held by its contacts (``standing``, ``gain`` rad/s). Shared by
    :func:`run_loop` and the robot loop's sim backend."""

    def __init__(
        self, scene: MujocoScene, control_period: float, *, gain: float | None = None,
        standing: StandingSupport | None = None,
    ):
        substeps = int(round(control_period / scene.timestep))
        if substeps < 1 or abs(substeps * scene.timestep - control_period) > 1e-9:
            raise BadInputError(
                f"control period {control_period} s is not a whole number of timesteps ({scene.timestep} s)"
            )
        self.scene = scene
        self.control_period = control_period
        self.substeps = substeps
        stiffness = scene.plant.servo_stiffness if standing is None else ()
        if stiffness:  # the arm's joint impedance (``sim.plant``'s servo_stiffness)
            self.servo = JointImpedanceServo(scene.model, scene.data, stiffness)
        else:
            gain = scene.plant.servo_gain if gain is None else gain
            self.servo = ComputedTorqueServo(scene.model, scene.data, gain, standing)
        self.standing = standing
        if standing is None:
            # centre-to-wall distance beyond which the tool cannot touch the wall within one period
            # (at up to CLEARANCE_SPEED m/s): the wall's normal n and the clearance plus n . point,
            # the bound of n . p for a centre p
            clearance = scene.tool.geometry.bounding_radius + CLEARANCE_SPEED * control_period
            self._wall_normal = tuple(float(x) for x in scene.surface.normal)
            self._wall_bound = clearance + float(scene.surface.normal @ scene.surface.point)
            self.contact_geom, environment = scene.tool_geom, (scene.wall_geom,)
        else:
            self.contact_geom, environment = scene.hand_geom, (scene.wall_geom, *scene.ground_geoms)
        self.contact_forces = ContactForces(scene.model, scene.data, environment)

    def prepare(self) -> None:
        """Load (or compile) the compiled kernels of a period now, the plant's state left as it
        was: the first call of each loads it from numba's cache (or compiles it), milliseconds
        that, on a real-time backend (``sim.sim_backend.SimRobot``), would fall into its first
        period or its first contact's."""
        self.servo.prepare()
        self.contact_forces.prepare()

    def reset(self, q0: np.ndarray, dq0: np.ndarray | None = None, servo_reference=None) -> None:
        """Put the plant at the Pinocchio state (q0, dq0) (None: at rest); the servo reference at
        the joints' state or at ``servo_reference``."""
        self.scene.set_state(q0, dq0)
        data, servo = self.scene.data, self.servo
        if servo_reference is None:
            servo_reference = data.qpos[servo.coordinates], data.qvel[servo.joints]
        servo.reset(*servo_reference)

    def advance(self, dq_cmd: np.ndarray, force: np.ndarray, held: HeldContactLog | None = None) -> np.ndarray:
        """One period under the command; adds the wall's contact force on the robot (world frame)
        of each substep to the rows of ``force`` (substeps, 3) and, with held contacts, records
        the floor and the soles in ``held``; returns the servo torque (the servo's buffer: copy it
        to keep it); ``held`` None: the held contacts are not recorded."""
        if self.standing is not None:
            return self._advance_standing(dq_cmd, force, held)
        if isinstance(self.servo, JointImpedanceServo):
            return self._advance_impedance(dq_cmd, force)
        scene = self.scene
        model, data, tool = scene.model, scene.data, self.contact_geom
        mujoco.mj_step1(model, data)
        torque = self.servo.torque(dq_cmd, self.control_period)
        data.qfrc_applied[:] = torque
        mujoco.mj_step2(model, data)
        (n0, n1, n2), (x, y, z) = self._wall_normal, data.geom_xpos[tool].tolist()
        if n0 * x + n1 * y + n2 * z > self._wall_bound:
            # the tool cannot reach the wall within this period: no contact force to log
            mujoco.mj_step(model, data, self.substeps - 1)
            return torque
        add = self.contact_forces.add
        for i in range(self.substeps):
            if i > 0:
                mujoco.mj_step(model, data)
            if data.ncon:
                add(force[i])
        return torque

    def _advance_impedance(self, dq_cmd: np.ndarray, force: np.ndarray) -> np.ndarray:
        """One period of an arm under its joint impedance, the torque recomputed at every
        physics step (``JointImpedanceServo.torque_at``); returns the period's first torque."""
        model, data, servo, h = self.scene.model, self.scene.data, self.servo, self.scene.timestep
        add = self.contact_forces.add
        first = None
        for i in range(self.substeps):
            mujoco.mj_step1(model, data)
            data.qfrc_applied[:] = servo.torque(dq_cmd, self.control_period) if i == 0 else servo.torque_at(i * h)
            first = data.qfrc_applied.copy() if i == 0 else first
            mujoco.mj_step2(model, data)
            if data.ncon:
                add(force[i])
        return first

    def _advance_standing(self, dq_cmd: np.ndarray, force: np.ndarray, held: HeldContactLog) -> np.ndarray:
        """One period of a robot held by its contacts (the servo before the first physics step)."""
        model, data, add = self.scene.model, self.scene.data, self.contact_forces.add
        torque = self.servo.torque(dq_cmd, self.control_period)
        for i in range(self.substeps):
            data.qfrc_applied[self.standing.base_nv:] = torque
            mujoco.mj_step(model, data)
            floor = np.zeros(3)
            add(force[i], floor)
            if held is not None:
                held.add_substep(floor, model.opt.timestep)
        return torque


@dataclass(frozen=True)
class Ending:
    """When a trial ends: after ``steps`` control steps, or, once the wall is touched (at step
    k_c), at k_c + ``after``; the source is told to stop at k_c + ``stop_after`` and the servo then
    holds the joints (``hold``). None: no such rule."""

    steps: int
    after: int | None = None
    stop_after: int | None = None
    hold: bool = False


@dataclass
class LoopRecord:
    """What :func:`run_loop` recorded: per control step the time, the state (Pinocchio convention:
    a floating base's coordinates first), the servo torque and the command; per physics step the
    wall force on the robot; the first control step with a wall contact force (None: none, or no
    ``Ending.after`` rule to watch for it), the
    held contacts' log (None without) and the loop's wall-clock time (s)."""

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    dq_cmd: np.ndarray
    force_t: np.ndarray
    force: np.ndarray
    first_contact: int | None
    held: HeldContactLog | None
    wall_time: float


def run_loop(plant: ServoedPlant, source: CommandSource, ending: Ending) -> LoopRecord:
    """Run the closed loop of the module docstring from the plant's current state."""
    scene = plant.scene
    data, substeps, period = scene.data, plant.substeps, plant.control_period
    base_nq, base_nv = scene.base_nq, scene.base_nv
    nv, joints = scene.model.nv, scene.model.nv - base_nv
    rows = ending.steps + (ending.after or 0)
    q, dq = np.empty((rows, scene.model.nq)), np.empty((rows, nv))  # Pinocchio's sizes are MuJoCo's
    tau, dq_cmd = np.empty((rows, joints)), np.empty((rows, joints))
    force = np.zeros((rows * substeps, 3))
    held = HeldContactLog.of(scene, rows) if plant.standing is not None else None
    first_contact, stop_at, end = None, None, ending.steps
    watch = ending.after is not None  # the first wall contact sets the ending
    advance, command_of = plant.advance, source.step
    start = time.perf_counter()
    k = 0
    while k < end:
        if base_nq:
            q[k], dq[k] = to_pinocchio(data.qpos, data.qvel, base_nq)
        else:
            q[k], dq[k] = data.qpos, data.qvel
        if held is not None:
            held.add_state(k)
        if k == stop_at:
            source.stop()
            if ending.hold:
                plant.servo.hold()
        command = np.asarray(command_of(q[k].copy(), dq[k].copy()).dq_cmd, dtype=float)
        if command.shape != (joints,) or not all_finite(command):
            raise ValueError(f"control step {k}: dq_cmd must be {joints} finite values, got {command}")
        dq_cmd[k] = command
        rows_k = force[k * substeps:(k + 1) * substeps]
        tau[k] = advance(command, rows_k, held)
        if watch and first_contact is None and any_nonzero(rows_k):
            first_contact = k
            stop_at = k + ending.stop_after if ending.stop_after is not None else None
            end = k + ending.after
        k += 1
    wall_time = time.perf_counter() - start
    return LoopRecord(
        np.arange(k) * period, q[:k], dq[:k], tau[:k], dq_cmd[:k], np.arange(k * substeps) * scene.timestep,
        force[:k * substeps], first_contact, held.truncated(k) if held is not None else None, wall_time,
    )
