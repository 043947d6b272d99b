"""The plant's joint servo: a computed-torque joint PD with acceleration feed-forward that tracks the
commanded joint velocity (kinematic control, a plant property), one torque per control period
(zero-order hold, like a robot's own 1 kHz torque loop), for a fixed-base arm and a standing robot.

A command dq_cmd_k is the joint velocity to reach at the end of period k, so the reference is
piecewise constant in acceleration:

    ddq_ref_k = (dq_cmd_k - dq_ref_k) / dt,   dq_ref_{k+1} = dq_cmd_k,
    q_ref_{k+1} = q_ref_k + dt (dq_ref_k + dq_cmd_k) / 2,     (q_ref, dq_ref)(0) = (q, dq)(0),
    a_k = ddq_ref_k + omega^2 (q_ref_k - q_k) + 2 omega (dq_ref_k - dq_k),

critically damped with bandwidth omega. The torque of the joints:

- fixed base (no held contacts): tau_k = M(q_k) a_k + h(q_k, dq_k), MuJoCo's M (with armature and
  payload) and bias forces h (Coriolis, centrifugal, gravity: ``qfrc_bias``) of the current state;
- floating base held by its contacts (:class:`StandingSupport`): tau_k = M_f a_k + h_j - tau_held,
  clipped at the URDF's effort limits. M_f = M_jj - M_jb M_bb^-1 M_bj is the joints' inertia with
  the base floating (the Schur complement of MuJoCo's M; the plain joint block M_jj overestimates
  it and makes a stiff servo unstable at 1 kHz), and tau_held = (Jf^T w)_j the joint torques of
  the least-norm held-contact wrenches w that carry the robot's weight in the measured
  configuration (S^T tau + Jf^T w = g at rest on the reference: Pinocchio, every control step).
  The base is not actuated; a real motor gives no more than its effort limit, so a hard stop or a
  large tracking error saturates the drive instead of asking for unbounded torque.

With no base (base_nv = 0) and no held contacts the second law, unclipped, is the first: M_f = M,
tau_held = 0.

**The ankles carry the body.** At a held contact's ankle (the joints of its chain within the
sole's ``depth`` of the contact frame: the G1's ankle pitch and roll) M_f is the foot's inertia,
but with the sole on the ground the ankle's torque turns the whole body about the ankle's axis;
and tau_held carries the weight wherever the CoM is: with M_f alone the body is in neutral balance
about its ankles (a push or an impact's momentum is stopped only by what the other joints do).
Each ankle joint i gets the PD of the body's pendulum about its axis a_i through the joint's
anchor p_i, on the servo's own errors:

    tau_i += I_i (omega_a^2 (q_ref,i - q_i) + 2 omega_a (dq_ref,i - dq_i)),
    I_i = m |(c - p_i) - ((c - p_i) . a_i) a_i|^2 / n_held,

m the robot's mass, c its CoM, n_held the held contacts that share the body (the point-mass
inertia of the body about the axis, the centroidal inertia left out), critically damped at the
bandwidth omega_a = :data:`ANKLE_BANDWIDTH`, below the body's own pendulum frequency
sqrt(g / (c_z - p_z)) (about 4 rad/s): the ankle's damping acts during the impact too, and a
stiffer one lifts a heel.

A fixed-base arm may take a **joint impedance** instead (:class:`JointImpedanceServo`, the plant's
``servo_stiffness``): the same reference and feed-forward, a diagonal feedback of stiffness K_i
(N m/rad per joint), critically damped at the current state, D_i = 2 sqrt(K_i M_ii(q)):

    tau_k = M(q_k) ddq_ref_k + K (q_ref_k - q_k) + D (dq_ref_k - dq_k) + h(q_k, dq_k).

The computed-torque feedback M (omega^2 e + 2 omega de) is the joint stiffness omega^2 M, which
pushes back along M^-1's directions only; a diagonal K (a real arm's joint impedance, e.g. a
Franka's default 2000 to 3000 N m/rad) holds each joint by its own stiffness.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import mujoco
import numpy as np
import pinocchio as pin
from numba import njit

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.max_speed import weight_wrenches

from .scene import to_pinocchio

ANKLE_BANDWIDTH = 0.5
"""rad/s: omega_a, the bandwidth of the ankles' PD on the body's pendulum (module docstring)."""


@njit(cache=True)
def reference_step(dq_cmd, q, dq, dt, kp, kd, reference, errors):
    """Kernel of one period's reference (module docstring): the errors e = q_ref - q (row 0 of
    ``errors``) and de = dq_ref - dq (row 1), the acceleration a = ddq_ref + kp e + kd de (row 2),
    then the reference (rows 0 and 1 of ``reference``: q_ref, dq_ref) advanced to the period's
    end under dq_cmd."""
    half = 0.5 * dt
    for i in range(q.shape[0]):
        e = reference[0, i] - q[i]
        de = reference[1, i] - dq[i]
        errors[0, i] = e
        errors[1, i] = de
        errors[2, i] = (dq_cmd[i] - reference[1, i]) / dt + (kp * e + kd * de)
        reference[0, i] += half * (reference[1, i] + dq_cmd[i])
        reference[1, i] = dq_cmd[i]


@njit(cache=True)
def impedance_torque(stiffness, M, period, elapsed, q, dq, bias, torque):
    """Kernel of the joint impedance's torque ``elapsed`` s into the period (module docstring):
    adds K (q_ref - q) + D (dq_ref - dq) + h to ``torque`` (which holds M ddq_ref), the reference
    q_ref = q_0 + s dq_0 + s^2 ddq_ref / 2, dq_ref = dq_0 + s ddq_ref (``period``'s rows: q_0,
    dq_0 at the period's start and ddq_ref), D_i = 2 sqrt(K_i M_ii)."""
    quadratic = 0.5 * elapsed**2
    for i in range(q.shape[0]):
        damping = 2.0 * np.sqrt(stiffness[i] * M[i, i])
        q_ref = period[0, i] + elapsed * period[1, i] + quadratic * period[2, i]
        dq_ref = period[1, i] + elapsed * period[2, i]
        torque[i] += stiffness[i] * (q_ref - q[i]) + damping * (dq_ref - dq[i]) + bias[i]


@dataclass(frozen=True)
class StandingSupport:
    """What a floating-base robot held by its contacts adds to the servo: its model (the held
    contacts' wrenches, the effort limits ``robot.tau_max``) and the free joint's sizes in MuJoCo's
    qpos (``base_nq``) and qvel (``base_nv``), before the joints'."""

    robot: RobotModel
    base_nq: int
    base_nv: int

    def torques(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """tau_held (one per joint): the joint torques of the least-norm held-contact wrenches
        carrying the robot's weight in the configuration qpos (module docstring)."""
        q = to_pinocchio(qpos, qvel, self.base_nq)[0]
        held_jacobian = self.robot.held_jacobian(q)  # the kinematics alone: this runs every period
        return held_jacobian[:, self.robot.base_nv:].T @ weight_wrenches(self.robot, q, held_jacobian)

    @cached_property
    def ankles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, pin.Data]:
        """The ankle joints (module docstring): their indices among the joints, their Pinocchio
        joint ids and axes (in their own frames), and a Pinocchio data of their own; found at the
        model's neutral posture."""
        model = self.robot.model
        data = model.createData()
        neutral = pin.neutral(model)
        pin.framesForwardKinematics(model, data, neutral)
        pin.computeJointJacobians(model, data, neutral)
        joints = []
        for contact in self.robot.description.held_contacts:
            frame = model.getFrameId(contact.frame)
            anchor, joint = data.oMf[frame].translation, model.frames[frame].parentJoint
            while joint > 0 and np.linalg.norm(data.oMi[joint].translation - anchor) <= contact.depth:
                joints.append(joint)
                joint = model.parents[joint]
        columns = [model.idx_vs[j] for j in joints]
        axes = np.array([pin.getJointJacobian(model, data, j, pin.LOCAL)[3:, c] for j, c in zip(joints, columns)])
        return np.array(columns, dtype=int) - self.robot.base_nv, np.array(joints, dtype=int), axes, data

    def ankle_inertias(self, qpos: np.ndarray) -> np.ndarray:
        """I_i of each ankle joint (in the order of :attr:`ankles`): the body's point-mass
        inertia about the joint's axis, shared by the held contacts (module docstring)."""
        model, robot = self.robot.model, self.robot
        _, ids, axes, data = self.ankles
        q = to_pinocchio(qpos, np.zeros(model.nv), self.base_nq)[0]
        com = pin.centerOfMass(model, data, q, False)
        mass = data.mass[0]
        inertias = np.empty(len(ids))
        for k, joint in enumerate(ids):
            placement = data.oMi[int(joint)]
            axis = placement.rotation @ axes[k]
            lever = com - placement.translation
            lever -= (lever @ axis) * axis
            inertias[k] = mass * (lever @ lever)
        return inertias / len(robot.description.held_contacts)


class ComputedTorqueServo:
    """The joint servo of the module docstring on the MuJoCo ``model`` and ``data``, with gain
    omega = ``gain`` (rad/s); ``standing`` for a floating-base robot held by its contacts (None: a
    fixed-base robot). The reference starts at the joints' state in ``data``.

    Uses MuJoCo's own M and h of the current state (``mj_step1`` computes them), so the servo sees
    the plant's armature and payload exactly.
    """

    def __init__(
        self, model: mujoco.MjModel, data: mujoco.MjData, gain: float, standing: StandingSupport | None = None
    ):
        self.model, self.data, self.standing = model, data, standing
        self.kp, self.kd = gain * gain, 2.0 * gain
        base_nq, base_nv = (standing.base_nq, standing.base_nv) if standing is not None else (0, 0)
        self.coordinates = slice(base_nq, None)  # the joints' part of qpos
        self.base, self.joints = slice(base_nv), slice(base_nv, None)  # the base's and the joints' qvel
        n = model.nv - base_nv
        self._reference = np.empty((2, n))  # q_ref, dq_ref
        self._errors = np.zeros((3, n))  # e, de, the acceleration a
        self._torque = np.zeros(n)
        self._M = np.empty((model.nv, model.nv))
        self.reset(data.qpos[self.coordinates], data.qvel[self.joints])

    @property
    def q_ref(self) -> np.ndarray:
        """The reference's joint positions (a view of the servo's buffer)."""
        return self._reference[0]

    @property
    def dq_ref(self) -> np.ndarray:
        """The reference's joint velocities (a view of the servo's buffer)."""
        return self._reference[1]

    def prepare(self) -> None:
        """Load (or compile) the servo's kernels now, on copies of its buffers: a kernel's first
        call loads it from numba's cache, milliseconds that must not fall into a real-time
        period. The servo's state is left as it was."""
        data, reference = self.data, self._reference.copy()
        reference_step(reference[1].copy(), data.qpos[self.coordinates], data.qvel[self.joints], 1.0, self.kp,
                       self.kd, reference, self._errors.copy())

    def reset(self, q: np.ndarray, dq: np.ndarray) -> None:
        """The reference at the joint state (q, dq)."""
        self._reference[0] = q
        self._reference[1] = dq

    def hold(self) -> None:
        """Re-anchor the reference at the measured joint positions, at rest: from now on the servo
        holds the joints where they are and only damps their velocities."""
        self.reset(self.data.qpos[self.coordinates], 0.0)

    def torque(self, dq_cmd: np.ndarray, dt: float) -> np.ndarray:
        """The joints' torque for the state in ``data`` (after ``mj_step1``); advances the
        reference. Returns the servo's buffer: copy it to keep it."""
        data, errors = self.data, self._errors
        reference_step(dq_cmd, data.qpos[self.coordinates], data.qvel[self.joints], dt, self.kp, self.kd,
                       self._reference, errors)
        if self.standing is None:
            mujoco.mj_mulM(self.model, data, self._torque, errors[2])
            self._torque += data.qfrc_bias
        else:
            self._standing_torque(errors[2], errors[0], errors[1])
        return self._torque

    def _standing_torque(self, acceleration: np.ndarray, position_error: np.ndarray, velocity_error: np.ndarray) -> None:
        """tau = M_f a + h_j - tau_held, plus the ankles' PD on the body's pendulum, clipped at
        the effort limits (module docstring)."""
        base, joints, data, standing = self.base, self.joints, self.data, self.standing
        mujoco.mj_fullM(self.model, data, self._M)
        M = self._M
        free_base = M[joints, joints] - M[joints, base] @ np.linalg.solve(M[base, base], M[base, joints])
        tau = free_base @ acceleration + data.qfrc_bias[joints] - standing.torques(data.qpos, data.qvel)
        ankles, omega = standing.ankles[0], ANKLE_BANDWIDTH
        tau[ankles] += standing.ankle_inertias(data.qpos) * (
            omega * omega * position_error[ankles] + 2.0 * omega * velocity_error[ankles]
        )
        tau_max = self.standing.robot.tau_max
        np.clip(tau, -tau_max, tau_max, out=self._torque)


class JointImpedanceServo(ComputedTorqueServo):
    """The joint impedance of the module docstring on a fixed-base arm's MuJoCo ``model`` and
    ``data``: stiffness ``stiffness`` (N m/rad, one per joint), critically damped. A drive's joint
    controller runs faster than the 1 kHz command: the torque is recomputed at every physics step
    (``torque_at``) on the period's reference, q_ref(s) = q_ref_k + s dq_ref_k + s^2 ddq_ref_k / 2
    (held for the whole period, the feedback of this stiffness on a rigid arm without rotor
    inertia is unstable at 1 kHz against the wall)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, stiffness):
        super().__init__(model, data, 0.0)
        self.stiffness = np.asarray(stiffness, dtype=float)
        self._period = np.zeros((3, len(self.stiffness)))  # q_ref, dq_ref at the period's start; ddq_ref

    def torque(self, dq_cmd: np.ndarray, dt: float) -> np.ndarray:
        """The joints' torque at the start of a period for the state in ``data`` (after
        ``mj_step1``); advances the reference to the period's end. Returns the servo's buffer:
        copy it to keep it."""
        period, data = self._period, self.data
        period[:2] = self._reference
        # the gains are 0: the acceleration is the reference's, ddq_ref
        reference_step(dq_cmd, data.qpos, data.qvel, dt, 0.0, 0.0, self._reference, self._errors)
        period[2] = self._errors[2]
        return self.torque_at(0.0)

    def prepare(self) -> None:
        super().prepare()
        data = self.data
        impedance_torque(self.stiffness, self._M, self._period.copy(), 0.0, data.qpos, data.qvel, data.qfrc_bias,
                         self._torque.copy())

    def torque_at(self, elapsed: float) -> np.ndarray:
        """The torque ``elapsed`` s into the period that the last :meth:`torque` began, for the
        state in ``data`` (after ``mj_step1``): M ddq_ref + K e + D de + h."""
        data, period = self.data, self._period
        mujoco.mj_mulM(self.model, data, self._torque, period[2])
        mujoco.mj_fullM(self.model, data, self._M)
        impedance_torque(self.stiffness, self._M, period, elapsed, data.qpos, data.qvel, data.qfrc_bias, self._torque)
        return self._torque
