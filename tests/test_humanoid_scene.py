"""The MuJoCo scene of the G1 against the Pinocchio model (sim/humanoid_scene.py); what it shares
with the arm's (the URDF edits, the free joint's conventions): tests/test_scene.py."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.humanoid_scene import WALL_FRICTION, build_humanoid_scene, plant_armature
from impactqp.sim.scene import HAND_RADIUS, to_pinocchio

from conftest import g1_model


@pytest.fixture(scope="module")
def setup():
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["staggered"])
    return robot, q, build_humanoid_scene(robot, wall_x=0.6, armature=0.0)


def random_velocity(scene, seed=0):
    scene.data.qvel[:] = np.random.default_rng(seed).normal(0.0, 0.5, scene.model.nv)
    mujoco.mj_forward(scene.model, scene.data)


def test_mass_matrices_agree_up_to_the_base_velocity_convention(setup):
    """v_pin = T v_mj with T = diag(R^T, I): MuJoCo's M equals T^T M_pin T."""
    robot, q, scene = setup
    scene.set_state(q)
    M = scene.mass_matrix()
    T = np.eye(scene.model.nv)
    T[:3, :3] = pin.Quaternion(q[3:robot.base_nq]).matrix().T
    np.testing.assert_allclose(M, T.T @ robot.terms(q).M @ T, atol=1e-10)


def test_hand_velocity_agrees(setup):
    """The wrist link's velocity from MuJoCo (at the link's centre of mass) equals Pinocchio's of the
    converted state."""
    robot, q, scene = setup
    scene.set_state(q)
    random_velocity(scene)
    q_pin, v_pin = to_pinocchio(scene.data.qpos, scene.data.qvel, scene.base_nq)
    hand = robot.description.contact.frame
    body = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_BODY, hand)
    velocity = np.zeros(6)
    mujoco.mj_objectVelocity(scene.model, scene.data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
    pin.forwardKinematics(robot.model, robot.data, q_pin, v_pin)
    pin.updateFramePlacements(robot.model, robot.data)
    frame = robot.model.getFrameId(hand)
    twist = pin.getFrameVelocity(robot.model, robot.data, frame, pin.LOCAL_WORLD_ALIGNED)
    lever = scene.data.xipos[body] - robot.data.oMf[frame].translation
    np.testing.assert_allclose(velocity[3:], twist.linear + np.cross(twist.angular, lever), atol=1e-10)
    np.testing.assert_allclose(velocity[:3], twist.angular, atol=1e-10)


def test_hand_sphere_pole_is_the_contact_point(setup):
    robot, q, scene = setup
    scene.set_state(q)
    placement = robot.frame_placements(q)[robot.contact_frame_name]
    pole = scene.data.geom_xpos[scene.hand_geom] + HAND_RADIUS * scene.data.geom_xmat[scene.hand_geom].reshape(3, 3)[:, 0]
    np.testing.assert_allclose(pole, placement.translation, atol=1e-10)


@pytest.mark.parametrize("armature", [None, 0.05, "per joint"])
def test_armature_adds_rotor_inertia_to_the_joints_only(setup, armature):
    """M_plant = T^T M_pin T + diag(0, a): the G1's actuators by default, one number or one per joint."""
    robot, q, _ = setup
    per_joint = np.linspace(0.01, 0.3, robot.n_joints)
    given = per_joint if armature == "per joint" else armature
    expected = {None: joint_armature(robot.joint_names), 0.05: np.full(robot.n_joints, 0.05)}.get(armature, per_joint)
    scene = build_humanoid_scene(robot, wall_x=0.6, armature=given)
    scene.set_state(q)
    M = scene.mass_matrix()
    T = np.eye(scene.model.nv)
    T[:3, :3] = pin.Quaternion(q[3:robot.base_nq]).matrix().T
    rotor = np.diag(np.r_[np.zeros(robot.base_nv), expected])
    np.testing.assert_allclose(M, T.T @ robot.terms(q).M @ T + rotor, atol=1e-10)


@pytest.mark.parametrize("armature", [-0.1, [0.1] * (g1_model().n_joints - 1), True, float("nan")])
def test_a_bad_armature_is_bad_input(setup, armature):
    with pytest.raises(BadInputError, match="armature"):
        plant_armature(setup[0], armature)


def test_the_feet_stand_on_the_floor_and_only_the_pairs_collide(setup):
    """The held contacts add the floor and one pair per sole sphere at the contact's friction; the
    hand sphere and the wall are the other pair; no geom collides outside the pairs."""
    robot, _, scene = setup
    model = scene.model
    assert not model.geom_contype.any() and not model.geom_conaffinity.any()
    spheres = [g for foot in scene.soles.spheres for g in foot]
    assert len(spheres) == model.npair - 1 and len(spheres) >= 3 * len(robot.description.held_contacts)
    pairs = {frozenset((int(model.pair_geom1[i]), int(model.pair_geom2[i]))): model.pair_friction[i][0]
             for i in range(model.npair)}
    assert pairs[frozenset((scene.hand_geom, scene.wall_geom))] == WALL_FRICTION
    for k, foot in enumerate(scene.soles.spheres):
        for g in foot:
            assert model.geom_bodyid[g] == scene.foot_bodies[k]
            assert pairs[frozenset((g, scene.floor_geom))] == robot.description.held_contacts[k].friction
