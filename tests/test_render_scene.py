"""The render-only model of a scene (``sim.render_scene``): the robot's meshes as visual geoms of
no collision, and the scene's qpos layout, so that a logged configuration puts every body where
the simulated scene puts it."""

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import ARMS, g1_model
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.sim.render_scene import arm_render_scene, humanoid_render_scene
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.scene import build_scene, from_pinocchio


def body_positions(model, qpos):
    """The world position of every named body of ``model`` at ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return {model.body(b).name: data.xpos[b].copy() for b in range(1, model.nbody)}


def mesh_geoms(model):
    return [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]


@pytest.fixture(scope="module", params=ARMS)
def arm(request):
    scene = build_scene(DEFAULT_WALL, robot=request.param)
    return scene, arm_render_scene(scene.robot, scene.tool, scene.surface)


def test_the_arm_render_model_has_the_meshes_and_the_scene_none(arm):
    """The simulated scene keeps no link geometry (its physics is the URDF's inertias and the
    tool-wall pair); the render model has a mesh on every moving link, none colliding."""
    scene, render = arm
    assert mesh_geoms(scene.model) == []
    meshes = mesh_geoms(render.model)
    moving = {render.model.jnt_bodyid[j] for j in range(render.model.njnt)}
    assert moving <= {render.model.geom_bodyid[g] for g in meshes}
    assert not render.model.geom_contype.any() and not render.model.geom_conaffinity.any()
    assert render.model.npair == 1  # the tool-wall pair only: nothing else could collide


@settings(max_examples=10)
@given(st.data())
def test_a_configuration_puts_every_body_where_the_scene_does(arm, data):
    scene, render = arm
    low, high = scene.robot.q_min, scene.robot.q_max
    q = np.array([data.draw(st.floats(float(a), float(b))) for a, b in zip(low, high)])
    assert render.model.nq == scene.model.nq
    simulated, shown = body_positions(scene.model, q), body_positions(render.model, render.qpos(q))
    for name, position in simulated.items():
        np.testing.assert_allclose(shown[name], position, atol=1e-12, err_msg=name)


def test_the_standing_robot_replays_on_its_render_model():
    robot = g1_model()
    scene = build_humanoid_scene(robot, 0.4)
    render = humanoid_render_scene(robot.description, tuple(robot.joint_names), 0.4, robot.urdf_path)
    assert render.model.nq == scene.model.nq and render.base_nq == scene.base_nq
    assert len(mesh_geoms(render.model)) >= len(ROBOTS["g1"].joints)
    rng = np.random.default_rng(0)
    quaternion = rng.normal(size=4)  # Pinocchio's (x, y, z, w), a turned base
    q = np.concatenate([[0.1, -0.2, 0.8], quaternion / np.linalg.norm(quaternion),
                        rng.uniform(-0.3, 0.3, robot.nq - robot.base_nq)])
    simulated = body_positions(scene.model, from_pinocchio(q, scene.base_nq))
    shown = body_positions(render.model, render.qpos(q))
    for name, position in simulated.items():
        np.testing.assert_allclose(shown[name], position, atol=1e-12, err_msg=name)


def test_the_render_model_draws_the_step_of_a_raised_sole():
    """A stance that raises a sole stands it on a box in the scene (``add_steps``); the render model
    draws the same box (name, place, size), of no collision, and no box for a flat stance."""
    robot = g1_model()
    stances = robot.description.stances
    step = stances["step"]
    scene = build_humanoid_scene(robot, 0.4, stance=step)
    render = humanoid_render_scene(robot.description, tuple(robot.joint_names), 0.4, robot.urdf_path, step)
    boxes = [g for g in range(render.model.ngeom) if render.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
    assert [render.model.geom(g).name for g in boxes] == [scene.model.geom(g).name for g in scene.step_geoms]
    raised = [k for k in range(len(step.feet)) if step.height(k) > 0.0]
    for g, k in zip(boxes, raised):
        shown, simulated = render.model.geom(g), scene.model.geom(scene.step_geoms[raised.index(k)])
        np.testing.assert_allclose(shown.pos, simulated.pos, atol=1e-12)
        np.testing.assert_allclose(shown.size, simulated.size, atol=1e-12)
        assert shown.pos[2] + shown.size[2] == pytest.approx(step.height(k))  # its top under the raised sole
        assert shown.contype[0] == 0 and shown.conaffinity[0] == 0
    flat = humanoid_render_scene(robot.description, tuple(robot.joint_names), 0.4, robot.urdf_path, stances["parallel"])
    assert not any(flat.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX for g in range(flat.model.ngeom))
