"""The standing G1's scene (``sim.humanoid_scene``) against the Pinocchio model: its mass matrix
up to the base velocity convention, hand velocity and sphere, rotor inertias, feet on the floor,
and a step under a raised sole."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import g1_model

from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.sim.humanoid_scene import build_humanoid_scene, plant_armature
from impactqp.sim.runner import standing_wall_friction
from impactqp.sim.trial_sources import SCRIPTED, QpCommand
from impactqp.sim.scene import HAND_RADIUS, WALL_FRICTION, to_pinocchio

G1 = RobotModel("g1")
G1_SCENE = build_humanoid_scene(G1, wall_x=0.6, armature=0.0)


@pytest.fixture(scope="module")
def setup():
    """The G1, its staggered stance and its link-only scene (G1_SCENE)."""
    return G1, stance_posture(G1, STANCES["staggered"]), G1_SCENE


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




def wall_pair_friction(scene) -> float:
    """The sliding friction of the scene's hand/wall contact pair (MuJoCo's model)."""
    model = scene.model
    for i in range(model.npair):
        if {int(model.pair_geom1[i]), int(model.pair_geom2[i])} == {scene.hand_geom, scene.wall_geom}:
            return float(model.pair_friction[i][0])
    raise AssertionError("no hand/wall pair")


@pytest.mark.parametrize(
    "source, mu",
    [(SCRIPTED, WALL_FRICTION), (QpCommand(), WALL_FRICTION), (QpCommand(friction=0.3), 0.3), (QpCommand(friction=0.0), 0.0)],
)
def test_the_wall_takes_the_friction_the_qp_rows_were_given(source, mu):
    """The standing trial's wall (``sim.runner.standing_wall_friction``): the mu of the QP's friction
    rows when it was given one, 0 included (``simulate --robot g1 --controller qp --friction 0``: a
    frictionless wall, as an arm's), else the paper's."""
    scene = build_humanoid_scene(G1, wall_x=0.6, armature=0.0, wall_friction=standing_wall_friction(source))
    assert wall_pair_friction(scene) == mu


@pytest.fixture(scope="module")
def step_scene():
    """The G1's step stance (its left sole on a 10 cm step), its posture and its scene."""
    stance = STANCES["step"]
    return stance, stance_posture(G1, stance), build_humanoid_scene(G1, wall_x=2.0, stance=stance)


def test_a_raised_sole_stands_on_a_box_whose_top_is_its_surface(step_scene):
    """One box per raised sole: its top at the stance's height, under the sole's corners, and
    paired with that sole's spheres only; the flat stances' scenes have none."""
    stance, q, scene = step_scene
    model = scene.model
    (box,) = scene.step_geoms
    assert scene.ground_geoms == (scene.floor_geom, box)
    top = model.geom_pos[box][2] + model.geom_size[box][2]
    assert top == pytest.approx(stance.heights[0])
    corners = G1.sole_corners(q)[:4]
    assert np.all(np.abs(corners[:, :2] - model.geom_pos[box][:2]) < model.geom_size[box][:2])
    pairs = [{int(model.pair_geom1[i]), int(model.pair_geom2[i])} for i in range(model.npair)]
    assert set().union(*(p for p in pairs if box in p)) - {box} == set(scene.soles.spheres[0])
    assert build_humanoid_scene(G1, wall_x=2.0, stance=STANCES["parallel"]).step_geoms == ()


def test_the_g1_stands_still_on_the_step_for_a_second(step_scene):
    """Under the standing servo the G1 stands 1 s on the step: neither foot frame moves by more
    than 0.1 mm, the pelvis stays up and the robot comes to rest."""
    from impactqp.sim.runner import SERVO_GAIN, SINK
    from impactqp.sim.servo import StandingSupport
    from impactqp.sim.sim_backend import SimRobot

    _, q, scene = step_scene
    start = q.copy()
    start[2] -= SINK
    robot = SimRobot(scene, start, np.zeros(G1.nv), 1e-3, paced=False, gain=SERVO_GAIN,
                     standing=StandingSupport(G1, scene.base_nq, scene.base_nv))

    def feet():
        q_now, v_now = to_pinocchio(scene.data.qpos, scene.data.qvel, scene.base_nq)
        placements = G1.frame_placements(q_now)
        return np.array([placements[c.frame].translation for c in G1.description.held_contacts]), q_now, v_now

    robot.hold(0.1)  # the soft floor takes the weight
    before, _, _ = feet()
    robot.hold(1.0)
    after, q_end, v_end = feet()
    assert np.abs(after - before).max() < 1e-4
    assert q_end[2] > 0.9 * q[2] and np.abs(v_end).max() < 0.05
