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

import mujoco
import numpy as np

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.max_speed import standing_wrenches

from .scene import to_pinocchio


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
        terms = self.robot.terms(to_pinocchio(qpos, qvel, self.base_nq)[0])
        return terms.held_jacobian[:, self.robot.base_nv:].T @ standing_wrenches(self.robot, terms)


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
        self.q_ref = data.qpos[self.coordinates].copy()
        self.dq_ref = data.qvel[self.joints].copy()
        n = model.nv - base_nv
        self._acceleration = np.zeros(n)
        self._torque = np.zeros(n)
        self._M = np.empty((model.nv, model.nv))

    def reset(self, q: np.ndarray, dq: np.ndarray) -> None:
        """The reference at the joint state (q, dq)."""
        self.q_ref = np.array(q, dtype=float)
        self.dq_ref = np.array(dq, dtype=float)

    def hold(self) -> None:
        """Re-anchor the reference at the measured joint positions, at rest: from now on the servo
        holds the joints where they are and only damps their velocities."""
        self.reset(self.data.qpos[self.coordinates], np.zeros_like(self.dq_ref))

    def torque(self, dq_cmd: np.ndarray, dt: float) -> np.ndarray:
        """The joints' torque for the state in ``data`` (after ``mj_step1``); advances the
        reference. Returns the servo's buffer: copy it to keep it."""
        data = self.data
        acceleration = self._acceleration
        acceleration[:] = (dq_cmd - self.dq_ref) / dt
        position_error = self.q_ref - data.qpos[self.coordinates]
        acceleration += self.kp * position_error + self.kd * (self.dq_ref - data.qvel[self.joints])
        if self.standing is None:
            mujoco.mj_mulM(self.model, data, self._torque, acceleration)
            self._torque += data.qfrc_bias
        else:
            self._standing_torque(acceleration)
        self.q_ref += 0.5 * dt * (self.dq_ref + dq_cmd)
        self.dq_ref[:] = dq_cmd
        return self._torque

    def _standing_torque(self, acceleration: np.ndarray) -> None:
        """tau = M_f a + h_j - tau_held, clipped at the effort limits (module docstring)."""
        base, joints, data = self.base, self.joints, self.data
        mujoco.mj_fullM(self.model, data, self._M)
        M = self._M
        free_base = M[joints, joints] - M[joints, base] @ np.linalg.solve(M[base, base], M[base, joints])
        tau = free_base @ acceleration + data.qfrc_bias[joints] - self.standing.torques(data.qpos, data.qvel)
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
        self._period = (self.q_ref.copy(), self.dq_ref.copy())  # the reference at the period's start

    def torque(self, dq_cmd: np.ndarray, dt: float) -> np.ndarray:
        """The joints' torque at the start of a period for the state in ``data`` (after
        ``mj_step1``); advances the reference to the period's end. Returns the servo's buffer:
        copy it to keep it."""
        self._period = (self.q_ref.copy(), self.dq_ref.copy())
        self._acceleration[:] = (dq_cmd - self.dq_ref) / dt
        self.q_ref += 0.5 * dt * (self.dq_ref + dq_cmd)
        self.dq_ref[:] = dq_cmd
        return self.torque_at(0.0)

    def torque_at(self, elapsed: float) -> np.ndarray:
        """The torque ``elapsed`` s into the period that the last :meth:`torque` began, for the
        state in ``data`` (after ``mj_step1``): M ddq_ref + K e + D de + h."""
        data, (q_start, dq_start), acceleration = self.data, self._period, self._acceleration
        mujoco.mj_mulM(self.model, data, self._torque, acceleration)
        mujoco.mj_fullM(self.model, data, self._M)
        damping = 2.0 * np.sqrt(self.stiffness * np.diag(self._M))
        q_ref = q_start + elapsed * dq_start + 0.5 * elapsed**2 * acceleration
        dq_ref = dq_start + elapsed * acceleration
        self._torque += self.stiffness * (q_ref - data.qpos) + damping * (dq_ref - data.qvel) + data.qfrc_bias
        return self._torque
