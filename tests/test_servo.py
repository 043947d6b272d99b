"""The plant's joint servo, one law for a fixed-base arm and a standing robot (sim/servo.py)."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.max_speed import standing_wrenches
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.robot import PandaModel
from impactqp.sim.humanoid_feet import LOAD, SoleSensor, lift_onset, slip_onset
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.runner import DEFAULT_CONTROL_PERIOD, SERVO_GAIN, SETTLE, SINK
from impactqp.sim.plant import PlantParameters
from impactqp.sim.scene import build_scene
from impactqp.sim.servo import ANKLE_BANDWIDTH, ComputedTorqueServo, JointImpedanceServo, StandingSupport
from impactqp.sim.trial_loop import ServoedPlant

ARM = PandaModel()
ARMATURE = np.linspace(0.1, 0.4, ARM.nv)
ARM_SCENE = build_scene(plant=PlantParameters(armature=tuple(ARMATURE)))
GAIN = 5.0
DT = 1e-3


def standing_servo(scene, robot: RobotModel) -> ComputedTorqueServo:
    standing = StandingSupport(robot, scene.base_nq, scene.base_nv)
    return ComputedTorqueServo(scene.model, scene.data, SERVO_GAIN, standing)


# ---------------------------------------------------------------------- fixed base: the arm
def arm_states():
    unit = st.lists(st.floats(0.05, 0.95), min_size=ARM.nv, max_size=ARM.nv).map(np.asarray)
    return st.tuples(unit, unit, unit).map(
        lambda u: (ARM.q_min + u[0] * (ARM.q_max - ARM.q_min), u[1] - 0.5, 20.0 * (u[2] - 0.5))
    )


@settings(max_examples=25, deadline=None)
@given(arm_states())
def test_on_its_reference_the_arm_servo_is_the_inverse_dynamics(state):
    """With the reference at the state and dq_cmd = dq + ddq dt, tau = (M + diag(armature)) ddq + h:
    Pinocchio's RNEA plus the rotor inertia, the acceleration the command asks for."""
    q, dq, ddq = state
    ARM_SCENE.set_state(q, dq)
    servo = ComputedTorqueServo(ARM_SCENE.model, ARM_SCENE.data, GAIN)
    tau = servo.torque(dq + ddq * DT, DT).copy()
    expected = pin.rnea(ARM.model, ARM.model.createData(), q, dq, ddq) + ARMATURE * ddq
    np.testing.assert_allclose(tau, expected, atol=1e-8 * max(1.0, np.abs(expected).max()))


@settings(max_examples=25, deadline=None)
@given(arm_states())
def test_the_arm_servo_feeds_back_the_tracking_error_critically_damped(state):
    """A reference (q_ref, dq_ref) away from the state and a command dq_cmd = dq_ref ask for the
    acceleration omega^2 (q_ref - q) + 2 omega (dq_ref - dq); the reference then advances by the
    trapezoid q_ref + dt (dq_ref + dq_cmd) / 2, dq_ref = dq_cmd."""
    q, dq, offset = state
    ARM_SCENE.set_state(q, dq)
    servo = ComputedTorqueServo(ARM_SCENE.model, ARM_SCENE.data, GAIN)
    q_ref, dq_ref = q + 0.01 * offset, dq - 0.05 * offset
    servo.reset(q_ref, dq_ref)
    tau = servo.torque(dq_ref, DT).copy()
    ddq = GAIN**2 * (q_ref - q) + 2.0 * GAIN * (dq_ref - dq)
    expected = pin.rnea(ARM.model, ARM.model.createData(), q, dq, ddq) + ARMATURE * ddq
    np.testing.assert_allclose(tau, expected, atol=1e-8 * max(1.0, np.abs(expected).max()))
    np.testing.assert_allclose(servo.q_ref, q_ref + DT * dq_ref, atol=1e-15)
    np.testing.assert_array_equal(servo.dq_ref, dq_ref)


def test_the_arm_servo_starts_at_the_state_and_holds_it():
    """The reference starts at the state in the data; ``hold`` re-anchors it at the joints, at rest."""
    q = 0.5 * (ARM.q_min + ARM.q_max)
    ARM_SCENE.set_state(q, np.full(ARM.nv, 0.1))
    servo = ComputedTorqueServo(ARM_SCENE.model, ARM_SCENE.data, GAIN)
    np.testing.assert_array_equal(servo.q_ref, q)
    np.testing.assert_array_equal(servo.dq_ref, np.full(ARM.nv, 0.1))
    servo.hold()
    np.testing.assert_array_equal(servo.q_ref, q)
    np.testing.assert_array_equal(servo.dq_ref, np.zeros(ARM.nv))


@settings(max_examples=25, deadline=None)
@given(arm_states(), st.lists(st.floats(10.0, 5000.0), min_size=ARM.nv, max_size=ARM.nv))
def test_the_joint_impedance_servo_is_the_feed_forward_plus_a_critically_damped_diagonal_feedback(state, stiffness):
    """Away from its reference the joint impedance asks tau = (M + diag(armature)) ddq_ref + K e +
    D de + h, D_i = 2 sqrt(K_i M_ii) with M_ii the diagonal of the plant's inertia (rotor
    included): Pinocchio's RNEA of ddq_ref, plus the joint-wise spring and damper; within the
    period, on the reference moved at the period's constant acceleration."""
    q, dq, offset = state
    K = np.asarray(stiffness)
    ARM_SCENE.set_state(q, dq)
    servo = JointImpedanceServo(ARM_SCENE.model, ARM_SCENE.data, K)
    q_ref, dq_ref, dq_cmd = q + 0.01 * offset, dq - 0.05 * offset, dq + 0.02 * offset
    servo.reset(q_ref, dq_ref)
    tau = servo.torque(dq_cmd, DT).copy()
    ddq_ref = (dq_cmd - dq_ref) / DT
    M = pin.crba(ARM.model, ARM.model.createData(), q) + np.diag(ARMATURE)
    D = 2.0 * np.sqrt(K * np.diag(M))
    expected = (pin.rnea(ARM.model, ARM.model.createData(), q, dq, ddq_ref) + ARMATURE * ddq_ref
                + K * (q_ref - q) + D * (dq_ref - dq))
    np.testing.assert_allclose(tau, expected, atol=1e-8 * max(1.0, np.abs(expected).max()))
    np.testing.assert_allclose(servo.q_ref, q_ref + 0.5 * DT * (dq_ref + dq_cmd), atol=1e-15)
    np.testing.assert_array_equal(servo.dq_ref, dq_cmd)
    elapsed = 0.4 * DT  # within the period: the reference moves at the period's acceleration
    q_at, dq_at = q_ref + elapsed * dq_ref + 0.5 * elapsed**2 * ddq_ref, dq_ref + elapsed * ddq_ref
    expected = (pin.rnea(ARM.model, ARM.model.createData(), q, dq, ddq_ref) + ARMATURE * ddq_ref
                + K * (q_at - q) + D * (dq_at - dq))
    np.testing.assert_allclose(servo.torque_at(elapsed), expected, atol=1e-8 * max(1.0, np.abs(expected).max()))


def test_a_plant_with_a_joint_stiffness_runs_the_joint_impedance_servo():
    stiff = build_scene(plant=PlantParameters(servo_stiffness=(3000.0,) * ARM.nv))
    assert isinstance(ServoedPlant(stiff, DEFAULT_CONTROL_PERIOD).servo, JointImpedanceServo)
    assert type(ServoedPlant(ARM_SCENE, DEFAULT_CONTROL_PERIOD).servo) is ComputedTorqueServo


# ---------------------------------------------------------------------- floating base: the standing G1
def test_the_servo_torque_saturates_at_the_urdf_effort_limits():
    """A command far beyond what the motors can give is clipped at each joint's effort limit."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    scene = build_humanoid_scene(robot, wall_x=1.0)
    scene.set_state(q)
    servo = standing_servo(scene, robot)
    tau = servo.torque(np.full(robot.n_joints, 1e3), DEFAULT_CONTROL_PERIOD)
    np.testing.assert_allclose(np.abs(tau), robot.model.effortLimit[robot.base_nv:])


@pytest.mark.parametrize("stance", ["wide", "staggered"])
def test_the_standing_g1_shows_no_foot_onset(stance):
    """Held by its servo with no command and no impact, after the settling: no slip, no lift."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES[stance])
    scene = build_humanoid_scene(robot, wall_x=2.0)
    start = q.copy()
    start[2] -= SINK
    scene.set_state(start)
    servo = standing_servo(scene, robot)
    sensor = SoleSensor(scene.model, scene.data, scene.soles)
    states = []
    for k in range(300):
        scene.data.qfrc_applied[scene.base_nv:] = servo.torque(np.zeros(robot.n_joints), DEFAULT_CONTROL_PERIOD)
        for _ in range(2):
            mujoco.mj_step(scene.model, scene.data)
        if k * DEFAULT_CONTROL_PERIOD >= SETTLE:
            states.append(sensor.read().copy())
    states = np.array(states)
    assert np.all(states[..., LOAD] > 0.0)
    assert not slip_onset(states).any() and not lift_onset(states).any()


def test_a_held_servo_only_damps_the_joints():
    """After ``hold`` the reference is the measured joint positions at rest: with a zero command the
    servo asks M_f (-2 w dq) of acceleration, no feed-forward and no position error; the ankles
    add their pendulum's damping, I_i (-2 omega_a dq_i)."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    scene = build_humanoid_scene(robot, wall_x=2.0)
    scene.set_state(q)
    servo = standing_servo(scene, robot)
    rng = np.random.default_rng(3)
    coordinates, base, joints = slice(scene.base_nq, None), slice(scene.base_nv), slice(scene.base_nv, None)
    scene.data.qpos[coordinates] += rng.uniform(-0.01, 0.01, robot.n_joints)  # the joints away from the reference
    scene.data.qvel[joints] = rng.uniform(-0.2, 0.2, robot.n_joints)  # and moving
    mujoco.mj_forward(scene.model, scene.data)
    servo.hold()
    np.testing.assert_array_equal(servo.q_ref, scene.data.qpos[coordinates])
    M = np.empty((scene.model.nv, scene.model.nv))
    mujoco.mj_fullM(scene.model, scene.data, M)
    free_base = M[joints, joints] - M[joints, base] @ np.linalg.solve(M[base, base], M[base, joints])
    held = servo.standing.torques(scene.data.qpos, scene.data.qvel)
    expected = free_base @ (-2.0 * SERVO_GAIN * scene.data.qvel[joints]) + scene.data.qfrc_bias[joints] - held
    ankles = servo.standing.ankles[0]
    expected[ankles] -= 2.0 * ANKLE_BANDWIDTH * servo.standing.ankle_inertias(scene.data.qpos) * scene.data.qvel[joints][ankles]
    tau = servo.torque(np.zeros(robot.n_joints), DEFAULT_CONTROL_PERIOD)
    np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_max, robot.tau_max), rtol=1e-9, atol=1e-9)


def test_the_standing_torques_hold_any_posture_in_equilibrium():
    """A servo at rest on its reference applies tau with S^T tau + Jf^T w = g in every row (base and
    joints), w the least-norm foot wrenches of the measured configuration: the body leaned by the
    waist is in equilibrium on its feet with no tracking error."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    q[robot.base_nq + robot.joint_index("waist_pitch_joint")] += 0.3
    scene = build_humanoid_scene(robot, wall_x=2.0)
    scene.set_state(q)
    servo = standing_servo(scene, robot)  # its reference: the state it starts from, at rest
    tau = servo.torque(np.zeros(robot.n_joints), DEFAULT_CONTROL_PERIOD)
    terms = robot.terms(q)
    gravity = pin.computeGeneralizedGravity(robot.model, robot.data, q)
    residual = terms.held_jacobian.T @ standing_wrenches(robot, terms) - gravity
    residual[robot.base_nv:] += tau
    np.testing.assert_allclose(residual, 0.0, atol=1e-6 * np.abs(gravity).max())


@pytest.mark.parametrize("stance", ["parallel", "step"])
def test_the_ankles_carry_the_body_s_pendulum_inertia(stance):
    """The ankle joints are those of each held contact's chain whose anchor lies within the sole's
    depth of its frame (the G1's ankle pitch and roll); each one's inertia is the robot's mass at
    the CoM's distance from the joint's axis, shared by the two feet: m |a x (c - p)|^2 / 2, the
    axis a the joint's column of the world-aligned angular Jacobian."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES[stance])
    scene = build_humanoid_scene(robot, wall_x=2.0, stance=STANCES[stance])
    scene.set_state(q)
    support = StandingSupport(robot, scene.base_nq, scene.base_nv)
    names = {robot.joint_names[i] for i in support.ankles[0]}
    assert names == {f"{side}_ankle_{axis}_joint" for side in ("left", "right") for axis in ("pitch", "roll")}
    model, data = robot.model, robot.model.createData()
    pin.computeJointJacobians(model, data, q)
    com = pin.centerOfMass(model, data, q)
    mass = sum(inertia.mass for inertia in model.inertias)
    expected = []
    for i in support.ankles[0]:
        joint = model.getJointId(robot.joint_names[i])
        axis = pin.getJointJacobian(model, data, joint, pin.LOCAL_WORLD_ALIGNED)[3:, robot.base_nv + i]
        expected.append(mass * np.linalg.norm(np.cross(axis, com - data.oMi[joint].translation)) ** 2 / 2)
    np.testing.assert_allclose(support.ankle_inertias(scene.data.qpos), expected, rtol=1e-9)
