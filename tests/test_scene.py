"""The MuJoCo scene is the same robot as the Pinocchio model, with one tool/wall contact pair; the
scene builder's parts every robot shares (the URDF edits, a floating base's free joint and its
conventions); the standing G1's scene against the Pinocchio model (its mass matrix up to the base
velocity convention, hand velocity and sphere, rotor inertias, feet on the floor)."""

from dataclasses import replace

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import ARMS, g1_model
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import TOOL_CENTRE_OFFSET, TOOL_RADIUS, PandaModel, RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.tool_description import TOOLS, Sphere
from impactqp.sim.plant import PlantParameters
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.humanoid_scene import build_humanoid_scene, plant_armature
from impactqp.sim.scene import (
    CONTACT_CONDIM,
    HAND_RADIUS,
    WALL_FRICTION,
    build_scene,
    from_pinocchio,
    mujoco_urdf,
    to_pinocchio,
)

ROBOT = PandaModel()
SCENE = build_scene()


def unit_postures():
    return st.lists(st.floats(0.0, 1.0), min_size=ROBOT.nq, max_size=ROBOT.nq).map(
        lambda u: ROBOT.q_min + np.asarray(u) * (ROBOT.q_max - ROBOT.q_min)
    )


@settings(max_examples=40, deadline=None)
@given(unit_postures())
def test_mass_matrix_equals_pinocchio(q):
    SCENE.set_state(q, np.zeros(ROBOT.nv))
    M_pin = pin.crba(ROBOT.model, ROBOT.data, q)
    M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
    assert np.abs(SCENE.mass_matrix() - M_pin).max() <= 1e-6 * np.abs(M_pin).max()


@settings(max_examples=20, deadline=None)
@given(unit_postures())
def test_tool_sphere_centre_is_the_pinocchio_tool_centre(q):
    SCENE.set_state(q, np.zeros(ROBOT.nv))
    hand = ROBOT.contact_frame(q)
    centre = hand.translation - TOOL_RADIUS * hand.rotation[:, 2]
    np.testing.assert_allclose(SCENE.tool_centre(), centre, atol=1e-9)
    np.testing.assert_allclose(SCENE.tool_centre(q + 0.1), ROBOT.contact_frame(q + 0.1).translation
                               - TOOL_RADIUS * ROBOT.contact_frame(q + 0.1).rotation[:, 2], atol=1e-9)
    np.testing.assert_allclose(SCENE.tool_centre(), centre, atol=1e-9)  # the state is untouched
    # the hand frame is TOOL_CENTRE_OFFSET behind the centre, on the same axis
    pin.framesForwardKinematics(ROBOT.model, ROBOT.data, q)
    np.testing.assert_allclose(
        ROBOT.data.oMf[ROBOT.hand_frame_id].translation + TOOL_CENTRE_OFFSET * hand.rotation[:, 2],
        centre,
        atol=1e-9,
    )


def test_only_the_tool_and_the_wall_collide():
    model = SCENE.model
    assert not model.geom_contype.any() and not model.geom_conaffinity.any()
    assert model.npair == 1
    assert {model.pair_geom1[0], model.pair_geom2[0]} == {SCENE.tool_geom, SCENE.wall_geom}
    assert model.pair_dim[0] == CONTACT_CONDIM
    assert model.geom_condim[SCENE.tool_geom] == model.geom_condim[SCENE.wall_geom] == CONTACT_CONDIM
    assert model.geom_size[SCENE.tool_geom][0] == TOOL_RADIUS
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.timestep <= 0.5e-3


@pytest.mark.parametrize("name", list(PANDA.postures))
def test_wall_touches_the_tool_at_the_impact_postures(name):
    SCENE.set_state(PANDA.postures[name].q, np.zeros(ROBOT.nv))
    # the posture puts the tip on the wall: the sphere's centre is one radius in front of it
    assert DEFAULT_WALL.signed_distance(SCENE.tool_centre()) == pytest.approx(TOOL_RADIUS, abs=1e-6)


def test_wall_pose_follows_the_surface():
    surface = Surface(point=np.array([0.0, 0.5, 0.0]), normal=np.array([0.0, -1.0, 0.0]))
    scene = build_scene(surface)
    wall = scene.wall_geom
    scene.set_state(np.zeros(scene.model.nq), np.zeros(scene.model.nv))
    np.testing.assert_allclose(scene.data.geom_xpos[wall], surface.point)
    np.testing.assert_allclose(scene.data.geom_xmat[wall].reshape(3, 3)[:, 2], surface.normal, atol=1e-12)


def test_friction_and_contact_parameters_default_to_the_papers():
    model = SCENE.model
    assert model.pair_friction[0][0] == pytest.approx(0.1123)
    np.testing.assert_allclose(model.pair_solref[0], PlantParameters().contact_solref)


@pytest.mark.parametrize("timestep", [0.0, 1e-3, float("nan")])
def test_bad_timestep_is_rejected(timestep):
    with pytest.raises(ValueError, match="timestep"):
        build_scene(timestep=timestep)


def test_contact_time_constant_below_two_timesteps_is_rejected():
    with pytest.raises(ValueError, match="twice the timestep"):
        build_scene(plant=PlantParameters(contact_solref=(0.0004, 1.0)))


# ---------------------------------------------------------------- every robot with every tool
SCENES = {(robot, tool): (build_scene(robot=robot, tool=tool), RobotModel(robot, tool))
          for robot in ARMS for tool in TOOLS}
MOST_JOINTS = max(len(ROBOTS[name].joints) for name in ARMS)


@pytest.mark.parametrize("robot, tool", list(SCENES), ids=[f"{r}-{t}" for r, t in SCENES])
@settings(max_examples=10, deadline=None)
@given(u=st.lists(st.floats(0.0, 1.0), min_size=MOST_JOINTS, max_size=MOST_JOINTS))  # the first nq serve a robot
def test_mass_matrix_equals_pinocchio_for_every_robot_and_tool(robot, tool, u):
    scene, model = SCENES[robot, tool]
    q = model.q_min + np.asarray(u)[: model.nq] * (model.q_max - model.q_min)
    scene.set_state(q, np.zeros(model.nv))
    M = pin.crba(model.model, model.data, q)
    M = np.triu(M) + np.triu(M, 1).T
    assert np.abs(scene.mass_matrix() - M).max() <= 1e-6 * np.abs(M).max()
    assert scene.model.body_mass.sum() == pytest.approx(sum(i.mass for i in model.model.inertias), abs=1e-9)


@pytest.mark.parametrize("robot, tool", list(SCENES), ids=[f"{r}-{t}" for r, t in SCENES])
def test_tool_geometry_sits_where_the_model_puts_it(robot, tool):
    scene, model = SCENES[robot, tool]
    geometry = model.tool.geometry
    q = model.description.postures[model.description.default_posture].q
    pin.framesForwardKinematics(model.model, model.data, q)
    frame = model.data.oMf[model.tool_frame_id]
    np.testing.assert_allclose(scene.tool_centre(q), frame.act(geometry.centre), atol=1e-9)
    if isinstance(geometry, Sphere):
        assert scene.model.geom_type[scene.tool_geom] == mujoco.mjtGeom.mjGEOM_SPHERE
        assert scene.model.geom_size[scene.tool_geom][0] == geometry.radius
    else:
        assert scene.model.geom_type[scene.tool_geom] == mujoco.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(scene.model.geom_size[scene.tool_geom], geometry.size / 2)
        data = mujoco.MjData(scene.model)
        data.qpos[:] = q
        mujoco.mj_kinematics(scene.model, data)
        np.testing.assert_allclose(data.geom_xmat[scene.tool_geom].reshape(3, 3), frame.rotation @ geometry.rotation,
                                   atol=1e-9)


@pytest.mark.parametrize("robot", ARMS)
def test_a_point_mass_tool_is_the_plants_payload(robot):
    """The tool's mass in the scene is the plant's payload of the same mass at the same place."""
    tip = TOOLS["impact_tip"]
    heavy = replace(tip, mass=0.8, com=tip.contact_point + [0.0, 0.0, 0.01])
    with_tool = build_scene(robot=robot, tool=heavy)
    with_payload = build_scene(robot=robot, plant=PlantParameters(payload_mass=0.8, payload_com=(0.0, 0.0, 0.01)))
    q = ROBOTS[robot].postures[ROBOTS[robot].default_posture].q
    for scene in (with_tool, with_payload):
        scene.set_state(q, np.zeros(scene.model.nv))
    np.testing.assert_allclose(with_tool.mass_matrix(), with_payload.mass_matrix(), atol=1e-12)


# ---------------------------------------------------------------- what every robot's scene shares
@pytest.mark.parametrize("robot", list(ROBOTS))
def test_the_urdf_is_edited_for_mujoco_with_the_urdf_inertias(robot):
    """No visual element, bare mesh file names, the fingers welded, and the compiler told to keep
    the URDF's inertias and bodies (module docstring of sim/scene.py)."""
    description = ROBOTS[robot]
    tool = None if description.floating else "impact_tip"
    root = ET.fromstring(mujoco_urdf(description, tool))
    assert not root.findall("link/visual")
    assert all("/" not in mesh.get("filename") for mesh in root.iter("mesh"))
    for joint in root.findall("joint"):
        if joint.get("name") in description.finger_joints:
            assert joint.get("type") == "fixed" and joint.find("mimic") is None
    compiler = root.find("mujoco/compiler")
    assert compiler.get("meshdir") == str(description.mesh_dir())
    assert (compiler.get("inertiafromgeom"), compiler.get("balanceinertia"), compiler.get("fusestatic")) == ("false",) * 3


G1 = RobotModel("g1")
G1_SCENE = build_humanoid_scene(G1, wall_x=0.6, armature=0.0)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=G1.model.nv + 4, max_size=G1.model.nv + 4))
def test_a_floating_base_state_round_trips_through_mujoco(u):
    """set_state takes Pinocchio's (q, v) (free flyer: quaternion (x, y, z, w), linear velocity in
    the base frame) and to_pinocchio gives them back; the base's linear velocity in MuJoCo is the
    same vector in world axes."""
    u = np.asarray(u)
    q = stance_posture(G1, STANCES["staggered"])
    q[3:G1.base_nq] = u[:4] / np.linalg.norm(u[:4]) if np.linalg.norm(u[:4]) > 0.1 else q[3:G1.base_nq]
    v = u[4:]
    G1_SCENE.set_state(q, v)
    back, v_back = to_pinocchio(G1_SCENE.data.qpos, G1_SCENE.data.qvel, G1_SCENE.base_nq)
    np.testing.assert_allclose(back, q, atol=1e-12)
    np.testing.assert_allclose(v_back, v, atol=1e-12)
    np.testing.assert_allclose(from_pinocchio(back, G1_SCENE.base_nq), G1_SCENE.data.qpos, atol=1e-12)
    R = pin.Quaternion(q[3:G1.base_nq]).matrix()
    np.testing.assert_allclose(G1_SCENE.data.qvel[:3], R @ v[:3], atol=1e-12)
    G1_SCENE.set_state(q)
    assert not G1_SCENE.data.qvel.any()


def test_a_fixed_base_has_no_free_joint_and_a_floating_base_one():
    """The free joint comes with the description's floating base, first, on the URDF's root link."""
    assert mujoco.mjtJoint.mjJNT_FREE not in SCENE.model.jnt_type and SCENE.base_nq == SCENE.base_nv == 0
    assert G1_SCENE.model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert (G1_SCENE.base_nq, G1_SCENE.base_nv) == (G1.base_nq, G1.base_nv)
    assert G1_SCENE.model.jnt_bodyid[0] == 1  # the first body under the world


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


@settings(max_examples=10)
@given(st.lists(st.floats(0.05, 5.0), min_size=7, max_size=7), st.lists(st.sampled_from([-1.0, 1.0]), min_size=7, max_size=7))
def test_joint_friction_bounds_each_joints_torque_and_takes_the_motions_energy(friction, signs):
    """Dry friction at the joints: a plant's joint friction f_j acts on joint j with a torque of
    at most f_j (MuJoCo's friction loss: a soft constraint on the accelerations), and a robot
    coasting without gravity or drive loses kinetic energy to it, while the nominal plant (no
    friction, no damping) keeps it."""
    far = Surface(point=np.array([3.0, 0.0, 0.0]), normal=np.array([-1.0, 0.0, 0.0]))  # no contact
    energies = {}
    for label, plant in (("friction", PlantParameters(joint_friction=friction)), ("nominal", PlantParameters())):
        scene = build_scene(far, plant=plant)
        model, data = scene.model, scene.data
        model.opt.gravity[:] = 0.0
        np.testing.assert_array_equal(model.dof_frictionloss[:7], friction if label == "friction" else 0.0)
        data.qpos[:7], data.qvel[:7] = PANDA.postures["elbow_up"].q, 0.5 * np.array(signs)
        mujoco.mj_forward(model, data)
        rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF)
        torque = np.zeros(model.nv)
        torque[data.efc_id[rows]] = data.efc_force[rows]  # a friction-loss row's force acts on its own dof
        assert np.all(np.abs(torque[:7]) <= np.array(plant.for_joints(7).joint_friction) * (1 + 1e-9))
        energy, most = 0.5 * data.qvel @ scene.mass_matrix() @ data.qvel, 0.0
        for _ in range(100):
            # the most friction can take in a step: each joint's torque bound times its path
            most += np.abs(data.qvel[:7]) @ np.array(plant.for_joints(7).joint_friction) * model.opt.timestep
            mujoco.mj_step(model, data)
        energies[label] = (energy, 0.5 * data.qvel @ scene.mass_matrix() @ data.qvel, most)
    (start, end, most), (nominal_start, nominal_end, _) = energies["friction"], energies["nominal"]
    assert nominal_end == pytest.approx(nominal_start, rel=1e-3)
    assert 10.0 * abs(nominal_start - nominal_end) < start - end <= 1.05 * most


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
