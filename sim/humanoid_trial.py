"""One simulated hand impact of the standing G1, and a campaign of them (docs/floating-base.md).

Trial: the robot starts at rest in a stance (``controller.model.humanoid_stance``), the wall
:data:`GAP` beyond its contact point. It stands still for :data:`SETTLE` s, then the right arm
(shoulder, elbow, wrist: 7 joints) is driven so that the hand moves along +x at ``speed``:
dq_arm = J_arm^+ v* (J_arm the 3x7 block of the contact Jacobian), reached by a 20 ms velocity
ramp; every other joint is commanded at rest. At the first wall contact (plus a 5 ms detection
latency) the command drops to zero; the trial goes on for :data:`AFTER` s to see whether the robot
stands.

Servo (the kinematic control, as the arm's ``sim.runner`` servo): a joint-space computed-torque PD
with acceleration feed-forward on the 29 joints, tau = M_f (ddq_ref + w^2 e + 2 w de) + h_j -
tau_feet, with M_f = M_jj - M_jb M_bb^-1 M_bj the joints' inertia with the base floating (the
Schur complement of MuJoCo's M; the plain joint block M_jj overestimates it and makes a stiff servo
unstable at 1 kHz), h the bias forces, and tau_feet = (Jf^T f)_j
the joint torques of the least-norm foot wrenches f that carry the robot's weight in the stance
(computed once, by Pinocchio). The base is not actuated. The torque each joint gets is clipped at
its URDF effort limit (5-139 N m): a real motor cannot give more, so a hard stop command or a
large tracking error saturates the drive instead of asking for unbounded torque.

Plant: MuJoCo's G1 with the actuators' reflected rotor inertias by default (``armature``:
``sim.humanoid_scene.plant_armature``; 0 for the link-only plant). The servo's M_f includes them
(MuJoCo's M does); the predictors do not (they keep the URDF model).

Measurement: the state before the impact is the last control step before the wall's first
contact force, the state after it the first control step after that first contiguous contact
ends (at most :data:`WINDOW` s later). The measured impulse is the integral of the wall force over
that contact. The jump is compared over the 29 joints with each predictor of
``controller.model.floating_base`` fed its own impulse, and with the feet-held momentum law fed
the measured impulse (``momentum``); the error is eq. (26), the mean of |predicted - measured|.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel, jump_from_impulse, predict
from impactqp.controller.model.humanoid_max_speed import ARM_JOINTS
from impactqp.controller.model.humanoid_stance import Stance, stance_posture

from .humanoid_scene import build_humanoid_scene, to_pinocchio

CONTROL_PERIOD = 1e-3
GAP = 0.02  # m from the contact point to the wall at the start
SETTLE = 0.1  # s standing still before the approach
RAMP = 0.02  # s of velocity ramp
LATENCY = 0.005  # s from the first contact to the stop command
AFTER = 0.4  # s simulated after the impact
SINK = 0.001  # m the soles start into the floor
WINDOW = 0.03  # s: longest first contact read as the impact
SERVO_GAIN = 40.0  # rad/s
SLIP = 0.005  # m of horizontal foot motion counted as a slip
LIFT = 0.005  # m of vertical foot motion counted as a lift
FAILURES = ("joint_velocity", "foot_slip", "foot_lift", "fell")
NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall's normal, towards the robot


@dataclass(frozen=True)
class ImpactTrial:
    """What one trial measured and predicted (joint jumps over the 29 joints, rad/s)."""

    stance: str
    speed: float  # commanded hand speed (m/s)
    contact_speed: float  # measured normal approach speed -n.v- (m/s)
    impulse: np.ndarray  # measured wall impulse on the robot (N s, world)
    floor_impulse: np.ndarray  # the floor's impulse on the feet over the same window (N s)
    duration: float  # length of the measurement window (s): the first contact
    measured_jump: np.ndarray  # (35) generalized-velocity jump, Pinocchio convention
    measured_com_jump: np.ndarray  # (3) m/s
    predicted_jump: dict  # method -> (35)
    predicted_com_jump: dict  # method -> (3)
    predicted_impulse: dict  # method -> (3)
    errors: dict  # method -> eq. (26) over the joints
    foot_slip: float  # largest horizontal foot displacement (m)
    foot_lift: float  # largest vertical foot displacement (m)
    fell: bool
    max_velocity_ratio: float  # largest |dq_i| / dq_max_i of the 29 joints after the settling
    max_velocity_joint: str  # the joint where it occurs
    failures: tuple  # every failure seen (FAILURES)
    first_failure: str  # the failure seen first (FAILURES), "" when none
    failure_time: float  # s from the first wall contact to that failure (< 0: before it; nan: none)
    wall_x: float  # m: the wall plane's position
    q_log: np.ndarray  # (steps, nq) Pinocchio configurations at the control rate
    contact_index: int  # the control step of the first wall contact

    @property
    def feasible(self) -> bool:
        """Did not fall, no foot slip or lift beyond the thresholds, no joint beyond its velocity limit."""
        return not self.first_failure

    @property
    def slipped(self) -> bool:
        return self.foot_slip > SLIP

    @property
    def lifted(self) -> bool:
        return self.foot_lift > LIFT


class _Servo:
    """The joint servo of the module docstring."""

    def __init__(self, scene, robot: FloatingBaseModel, q_pin: np.ndarray, gain: float):
        self.scene = scene
        self.kp, self.kd = gain * gain, 2.0 * gain
        terms = robot.terms(q_pin)
        gravity = pin.computeGeneralizedGravity(robot.model, robot.data, q_pin)
        feet = np.linalg.pinv(terms.Jf[:, :6].T) @ gravity[:6]
        self.tau_feet = terms.Jf[:, 6:].T @ feet
        self.tau_max = robot.tau_max
        self.q_ref = scene.data.qpos[7:].copy()
        self.dq_ref = np.zeros(29)
        self._M = np.empty((scene.model.nv, scene.model.nv))

    def torque(self, dq_cmd: np.ndarray, dt: float) -> np.ndarray:
        model, data = self.scene.model, self.scene.data
        acceleration = (dq_cmd - self.dq_ref) / dt
        acceleration += self.kp * (self.q_ref - data.qpos[7:]) + self.kd * (self.dq_ref - data.qvel[6:])
        mujoco.mj_fullM(model, data, self._M)
        M = self._M
        free_base = M[6:, 6:] - M[6:, :6] @ np.linalg.solve(M[:6, :6], M[:6, 6:])
        tau = np.clip(free_base @ acceleration + data.qfrc_bias[6:] - self.tau_feet, -self.tau_max, self.tau_max)
        self.q_ref += 0.5 * dt * (self.dq_ref + dq_cmd)
        self.dq_ref = dq_cmd.copy()
        return tau


def run_impact_trial(robot: FloatingBaseModel, stance: Stance, speed: float, *, gain: float = SERVO_GAIN,
                     armature=None, q0: np.ndarray | None = None, gap: float = GAP) -> ImpactTrial:
    """Simulate one trial (module docstring) and compare the jump with the predictors; ``gap``
    (m) is the start distance of the contact point from the wall, ``armature`` the plant's rotor
    inertia (``sim.humanoid_scene.plant_armature``: None for the G1's actuators)."""
    q0 = stance_posture(robot, stance) if q0 is None else q0
    contact0 = robot.frame_placements(q0)[robot.model.frames[robot.contact_frame_id].name].translation
    scene = build_humanoid_scene(robot, wall_x=float(contact0[0]) + gap, armature=armature)
    start = q0.copy()
    start[2] -= SINK  # the soft floor contact carries the weight from the first step
    scene.set_state(start)
    model, data = scene.model, scene.data
    servo = _Servo(scene, robot, q0, gain)
    substeps = int(round(CONTROL_PERIOD / model.opt.timestep))
    arm = np.array([robot.joint_index(j) for j in ARM_JOINTS])
    approach_steps = int(round((SETTLE + 3 * gap / speed + RAMP) / CONTROL_PERIOD))
    states, forces, floor_impulses, feet = [], [], [], []
    first_contact, stop_at, end = None, None, approach_steps
    k = 0
    while k < end:
        q_pin, v_pin = to_pinocchio(data.qpos, data.qvel)
        states.append((q_pin, v_pin))
        feet.append(data.xpos[list(scene.foot_bodies)].copy())
        dq_cmd = np.zeros(29)
        t = k * CONTROL_PERIOD
        if t >= SETTLE and (stop_at is None or k < stop_at):
            terms = robot.terms(q_pin)
            scale = min(1.0, (t - SETTLE) / RAMP)
            dq_cmd[arm] = np.linalg.pinv(terms.J[:, 6 + arm]) @ (-scale * speed * NORMAL)
        tau = servo.torque(dq_cmd, CONTROL_PERIOD)
        force, floor = np.zeros(3), np.zeros(3)
        for _ in range(substeps):
            data.qfrc_applied[6:] = tau
            mujoco.mj_step(model, data)
            wall_force, floor_force = _contact_forces(scene)
            force += wall_force * model.opt.timestep
            floor += floor_force * model.opt.timestep
        forces.append(force)
        floor_impulses.append(floor)
        if first_contact is None and np.any(force != 0.0):
            first_contact = k
            stop_at = k + int(round(LATENCY / CONTROL_PERIOD))
            end = k + int(round(AFTER / CONTROL_PERIOD))
        k += 1
    if first_contact is None:
        raise RuntimeError(f"the hand never reached the wall (stance {stance.name}, {speed} m/s)")
    log = (states, np.array(forces), np.array(floor_impulses), np.array(feet))
    return _evaluate(robot, stance, speed, log, first_contact, scene.wall_x)


def _contact_forces(scene) -> tuple[np.ndarray, np.ndarray]:
    """The wall's and the floor's contact forces on the robot (world frame) in the current step."""
    model, data = scene.model, scene.data
    wall, floor, wrench = np.zeros(3), np.zeros(3), np.zeros(6)
    for c in range(data.ncon):
        contact = data.contact[c]
        mujoco.mj_contactForce(model, data, c, wrench)
        on_geom2 = contact.frame.reshape(3, 3).T @ wrench[:3]
        # the environment (wall or floor) is geom1 or geom2 of the pair; the force on the robot
        on_robot = on_geom2 if contact.geom1 in (scene.wall_geom, scene.floor_geom) else -on_geom2
        if scene.wall_geom in (contact.geom1, contact.geom2):
            wall += on_robot
        else:
            floor += on_robot
    return wall, floor


def _evaluate(robot, stance, speed, log, first, wall_x) -> ImpactTrial:
    """Measured and predicted jumps of a simulated trial (module docstring)."""
    states, forces, floor_impulses, feet = log
    window = int(round(WINDOW / CONTROL_PERIOD))
    last = first
    while last + 1 < min(len(forces), first + window) and np.any(forces[last + 1] != 0.0):
        last += 1
    q_pre, v_pre = states[first]
    q_post, v_post = states[min(last + 1, len(states) - 1)]
    impulse = forces[first:last + 1].sum(axis=0)
    floor_impulse = floor_impulses[first:last + 1].sum(axis=0)
    terms = robot.terms(q_pre)
    v_minus = terms.J @ v_pre
    measured = v_post - v_pre
    post_terms = robot.terms(q_post)
    com_jump = post_terms.Jcom @ v_post - terms.Jcom @ v_pre
    predicted, com, impulses = {}, {}, {}
    for method in METHODS:
        jump = predict(terms, method, NORMAL, v_minus)
        predicted[method], com[method], impulses[method] = jump.dv, jump.com_jump, jump.impulse
    predicted["momentum"] = jump_from_impulse(terms, impulse)
    com["momentum"] = terms.Jcom @ predicted["momentum"]
    impulses["momentum"] = impulse
    errors = {m: float(np.mean(np.abs(dv[6:] - measured[6:]))) for m, dv in predicted.items()}
    start = int(round(SETTLE / CONTROL_PERIOD))
    moved = feet[start:] - feet[start]
    base_height = np.array([s[0][2] for s in states])
    base_up = np.array([pin.Quaternion(s[0][3:7]).matrix()[2, 2] for s in states])
    ratios = np.array([np.abs(s[1][6:]) / robot.dq_max for s in states[start:]])
    ratio = ratios.max(axis=1)
    fell = (base_height < 0.5 * base_height[0]) | (base_up < np.cos(np.radians(45.0)))
    failing = {
        "joint_velocity": ratio > 1.0,
        "foot_slip": np.linalg.norm(moved[..., :2], axis=-1).max(axis=1) > SLIP,
        "foot_lift": np.abs(moved[..., 2]).max(axis=1) > LIFT,
        "fell": fell[start:],
    }
    first_step = {name: int(np.argmax(flags)) for name, flags in failing.items() if np.any(flags)}
    failure = min(first_step, key=lambda name: (first_step[name], FAILURES.index(name)), default="")
    return ImpactTrial(
        stance=stance.name, speed=speed, contact_speed=float(-NORMAL @ v_minus), impulse=impulse,
        floor_impulse=floor_impulse, duration=(last + 1 - first) * CONTROL_PERIOD,
        measured_jump=measured, measured_com_jump=com_jump, predicted_jump=predicted,
        predicted_com_jump=com, predicted_impulse=impulses, errors=errors,
        foot_slip=float(np.linalg.norm(moved[..., :2], axis=-1).max()),
        foot_lift=float(np.abs(moved[..., 2]).max()),
        fell=bool(np.any(fell)), max_velocity_ratio=float(ratio.max()),
        max_velocity_joint=robot.joint_names[int(np.argmax(ratios.max(axis=0)))],
        failures=tuple(name for name in FAILURES if name in first_step), first_failure=failure,
        failure_time=(first_step[failure] + start - first) * CONTROL_PERIOD if failure else float("nan"),
        wall_x=wall_x, q_log=np.array([s[0] for s in states]), contact_index=first,
    )
