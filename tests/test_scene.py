"""The MuJoCo scene is the same robot as the Pinocchio model, with one tool/wall contact pair; the
scene builder's parts every robot shares (the URDF edits, a floating base's free joint and its
conventions, shown on the G1's scene). The standing robot's own scene: test_humanoid_scene.py."""

from dataclasses import replace

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import ARMS
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import TOOL_CENTRE_OFFSET, TOOL_RADIUS, PandaModel, RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.tool_description import TOOLS, Sphere
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.plant import PlantParameters
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.generation import tangential_direction
from impactqp.sim.scene import (
    CONTACT_CONDIM,
    NOSLIP_ITERATIONS,
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


def pressed_tangential_speeds(share: float, noslip_iterations: int, steps: int = 100) -> np.ndarray:
    """The tool at ``elbow_right`` on a wall of mu = 0.6, pressed by 20 N along -n and
    share x mu x 20 N along the wall's tangent, gravity and Coriolis compensated (the applied joint
    torque h + J^T f at every step): the contact's tangential speed after each 0.25 ms step."""
    normal = DEFAULT_WALL.normal
    scene = build_scene(Surface(DEFAULT_WALL.point, normal, 0.6), noslip_iterations=noslip_iterations)
    scene.set_state(PANDA.postures["elbow_right"].q)
    force = -20.0 * normal + share * 0.6 * 20.0 * tangential_direction(normal)
    speeds = []
    for _ in range(steps):
        J = ROBOT.terms(scene.data.qpos.copy()).J
        scene.data.qfrc_applied[:] = scene.data.qfrc_bias + J.T @ force
        mujoco.mj_step(scene.model, scene.data)
        assert scene.data.ncon == 1  # the tool stays on the wall
        v = ROBOT.terms(scene.data.qpos.copy()).J @ scene.data.qvel
        speeds.append(np.linalg.norm(v - (normal @ v) * normal))
    return np.array(speeds)


@pytest.mark.parametrize("share", [0.5, -0.5])
def test_noslip_holds_a_contact_pressed_inside_its_cone(share):
    """Coulomb: a contact whose tangential force is inside the cone (half of mu f_n, either way
    along the tangent) sticks. MuJoCo's soft friction lets it creep (a tenth of a mm/s here);
    noslip holds it still (a slide is left alone: ``tests/test_oblique.py``)."""
    soft, noslip = (pressed_tangential_speeds(share, n) for n in (0, NOSLIP_ITERATIONS))
    assert soft[-1] > 1e-4
    assert noslip.max() < 1e-6


def test_the_scenes_noslip_is_mujocos_default_unless_asked():
    assert SCENE.model.opt.noslip_iterations == 0
    assert build_scene(noslip_iterations=NOSLIP_ITERATIONS).model.opt.noslip_iterations == NOSLIP_ITERATIONS


@pytest.mark.parametrize("iterations", [-1, 1.5, True, 10**6])
def test_bad_noslip_iterations_are_rejected(iterations):
    with pytest.raises(BadInputError, match="noslip_iterations"):
        build_scene(noslip_iterations=iterations)


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
