"""The environment's contact force on the robot from MuJoCo's constraint forces
(sim/contact_force.py), contact by contact against MuJoCo's own ``mj_contactForce``."""

import mujoco
import numpy as np
import pytest

from impactqp.sim.contact_force import ContactForces

# A wall (geom 0) and a floor (geom 1) (condim 1: a contact takes the larger condim of its two geoms), bodies of every contact dimension falling on them at an
# angle, so that contacts have friction, normals along both surfaces and either geom order.
SCENE = """
<mujoco>
  <option timestep="0.002" cone="{cone}"/>
  <worldbody>
    <geom name="wall" type="plane" size="2 2 0.1" pos="0.3 0 0" zaxis="-1 0 0.2" condim="1"/>
    <geom name="floor" type="plane" size="2 2 0.1" condim="1"/>
    <body pos="0.1 0.0 0.3" euler="20 30 10"><freejoint/><geom type="box" size="0.05 0.04 0.03" condim="3"/></body>
    <body pos="0.0 0.2 0.25"><freejoint/><geom type="sphere" size="0.04" condim="1"/></body>
    <body pos="0.2 -0.2 0.2" euler="0 70 0"><freejoint/><geom type="capsule" size="0.03 0.08" condim="6"/></body>
    <body pos="0.15 0.3 0.3"><freejoint/><geom type="ellipsoid" size="0.05 0.03 0.04" condim="4"/></body>
  </worldbody>
</mujoco>
"""


def world_force_on_robot(model, data, c, environment):
    """MuJoCo's contact force of contact c, in the world frame, on the geom that is not the
    environment's (the robot's)."""
    wrench = np.zeros(6)
    mujoco.mj_contactForce(model, data, c, wrench)
    contact = data.contact[c]
    on_geom2 = contact.frame.reshape(3, 3).T @ wrench[:3]
    return on_geom2 if contact.geom1 in environment else -on_geom2


@pytest.fixture(scope="module")
def falling():
    """The scene's states over 0.6 s of falling, sliding and resting: (model, data) at each one
    that has contacts."""
    model = mujoco.MjModel.from_xml_string(SCENE.format(cone="elliptic"))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    data.qvel[:] = rng.normal(0.0, 1.0, model.nv)
    states = []
    for _ in range(300):
        mujoco.mj_step(model, data)
        if data.ncon:
            states.append((data.qpos.copy(), data.qvel.copy(), data.act.copy()))
    return model, states


def test_the_sums_are_mujoco_s_contact_forces_on_the_robot(falling):
    """Every contact's force (condim 1, 3, 4 and 6, either geom order) on the robot: one sum
    for wall and floor, or the wall's and the floor's apart."""
    model, states = falling
    data = mujoco.MjData(model)
    environment = (0, 1)
    forces = ContactForces(model, data, environment)
    dims, touched = set(), set()
    for qpos, qvel, act in states:
        data.qpos[:], data.qvel[:], data.act[:] = qpos, qvel, act
        mujoco.mj_step(model, data)
        if not data.ncon:
            continue
        dims |= set(data.contact.dim.tolist())
        touched |= set(data.contact.geom1.tolist()) | set(data.contact.geom2.tolist())
        each = [world_force_on_robot(model, data, c, environment) for c in range(data.ncon)]
        on_wall = [f for c, f in enumerate(each) if 0 in data.contact.geom[c]]
        together, wall, floor = np.zeros(3), np.zeros(3), np.zeros(3)
        forces.add(together)
        forces.add(wall, floor)
        scale = 1e-12 * max(1.0, max(np.abs(f).max() for f in each))
        np.testing.assert_allclose(together, np.sum(each, axis=0), atol=scale)
        np.testing.assert_allclose(wall, np.sum(on_wall, axis=0) if on_wall else np.zeros(3), atol=scale)
        np.testing.assert_allclose(floor, together - wall, atol=scale)
    assert dims >= {1, 3, 4, 6} and touched >= {0, 1}  # every dimension, the wall and the floor


def test_the_sum_adds_to_what_it_is_given_and_nothing_without_contacts(falling):
    model, states = falling
    data = mujoco.MjData(model)
    forces = ContactForces(model, data, (0, 1))
    wall = np.array([1.0, 2.0, 3.0])
    mujoco.mj_forward(model, data)  # the initial state, in the air
    assert data.ncon == 0
    forces.add(wall)
    np.testing.assert_array_equal(wall, [1.0, 2.0, 3.0])
    data.qpos[:], data.qvel[:], data.act[:] = states[-1]
    mujoco.mj_step(model, data)
    fresh = np.zeros(3)
    forces.add(fresh)
    forces.add(wall)
    np.testing.assert_allclose(wall, fresh + [1.0, 2.0, 3.0], rtol=1e-15)


def test_pyramidal_cones_are_refused():
    """The constraint forces of a pyramidal cone are not the contact force: an internal error."""
    model = mujoco.MjModel.from_xml_string(SCENE.format(cone="pyramidal"))
    with pytest.raises(ValueError, match="elliptic"):
        ContactForces(model, mujoco.MjData(model), (0, 1))
