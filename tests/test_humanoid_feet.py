"""The soles' measured contact state (sim/humanoid_feet.py), in a tiny scene: one rigid sole on
four spheres, loaded by its weight and pushed or twisted by a known external wrench."""

import mujoco
import numpy as np
import pytest

from impactqp.controller.model.humanoid_stance import edge_margins
from impactqp.sim.humanoid_feet import (
    CONE,
    LIFT_MARGIN,
    LOAD,
    MARGIN,
    SLIP_SPEED,
    SPEED,
    Soles,
    lift_onset,
    slip_onset,
    SoleSensor,
    worst,
)

MU = 1.0
MASS = 20.0
CORNERS = ((-0.05, 0.025), (-0.05, -0.025), (0.12, 0.03), (0.12, -0.03))  # the G1's sole spheres
PAIR = 'condim="3" friction="1 1 0 0 0" solref="0.005 1" solimp="0.95 0.99 0.001 0.5 2"'


def tiny_scene():
    spheres = "".join(f'<geom name="s{i}" type="sphere" size="0.005" pos="{x} {y} 0" mass="0.001"/>'
                      for i, (x, y) in enumerate(CORNERS))
    pairs = "".join(f'<pair geom1="s{i}" geom2="floor" {PAIR}/>' for i in range(4))
    xml = f"""<mujoco><option timestep="0.0005" integrator="implicitfast" cone="elliptic"/><worldbody>
    <geom name="floor" type="plane" size="2 2 0.01" contype="0" conaffinity="0"/>
    <body name="foot" pos="0 0 0.0049"><freejoint/>
    <geom type="box" size="0.085 0.03 0.004" pos="0.035 0 0.006" mass="{MASS}" contype="0" conaffinity="0"/>
    {spheres}</body></worldbody><contact>{pairs}</contact></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "foot")
    return model, mujoco.MjData(model), Soles.of(model, (body,), MU)


def reference_sole_state(model, data, soles):
    """The sole states of the module docstring, contact by contact from MuJoCo's own
    ``mj_contactForce`` and numpy: the plain twin of the compiled ``SoleSensor``."""
    n = len(soles.bodies)
    force, moment, speed = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros(n)
    wrench, twist = np.zeros(6), np.zeros((n, 6))
    foot_of = {g: k for k, foot in enumerate(soles.spheres) for g in foot}
    for k, body in enumerate(soles.bodies):
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, twist[k], 0)
    for c in range(data.ncon):
        contact = data.contact[c]
        k = foot_of.get(contact.geom1, foot_of.get(contact.geom2))
        if k is None:
            continue
        mujoco.mj_contactForce(model, data, c, wrench)
        f = contact.frame.reshape(3, 3).T @ wrench[:3]
        force[k] += f if f[2] >= 0.0 else -f
        body = soles.bodies[k]
        local = data.xmat[body].reshape(3, 3).T @ (contact.pos - data.xpos[body])
        moment[k] += wrench[0] * local[:2]
        point = twist[k, 3:] + np.cross(twist[k, :3], contact.pos - data.xipos[body])
        speed[k] = max(speed[k], float(np.linalg.norm(point[:2])))
    state = np.zeros((n, 4))
    for k in range(n):
        load = force[k, 2]
        state[k] = load, 0.0, -np.inf, speed[k]
        if load > 0.0:
            state[k, CONE] = np.linalg.norm(force[k, :2]) / (soles.friction[k] * load)
            state[k, MARGIN] = edge_margins(soles.polygons[k], moment[k] / load).min()
    return state


def run(wrench, seconds, settle=0.2):
    """Stand for ``settle`` s, then apply ``wrench`` (force, moment at the body's centre of mass):
    the sole states after the settling, worst per 1 ms."""
    model, data, soles = tiny_scene()
    sensor = SoleSensor(model, data, soles)
    states, step = [], None
    for k in range(int(round((settle + seconds) / model.opt.timestep))):
        data.xfrc_applied[1] = wrench if k * model.opt.timestep >= settle else 0.0
        mujoco.mj_step(model, data)
        now = sensor.read()
        reference = reference_sole_state(model, data, soles)
        np.testing.assert_allclose(now, reference, rtol=1e-12, atol=1e-12)
        if step is None:
            step = now.copy()
        else:
            before = step.copy()
            worst(step, now)
            np.testing.assert_array_equal(step[:, [LOAD, MARGIN]], np.minimum(before, now)[:, [LOAD, MARGIN]])
            np.testing.assert_array_equal(step[:, [CONE, SPEED]], np.maximum(before, now)[:, [CONE, SPEED]])
        if k % 2 == 1:
            if k * model.opt.timestep >= settle:
                states.append(step)
            step = None
    return np.array(states)


WEIGHT = MASS * 9.81


def test_a_standing_sole_carries_its_weight_with_no_onset():
    states = run(np.zeros(6), 0.3)
    assert states[:, 0, LOAD] == pytest.approx(WEIGHT, rel=0.01)
    assert not slip_onset(states).any() and not lift_onset(states).any()
    assert states[:, 0, CONE].max() < 1e-3


def test_centre_of_pressure_is_the_load_weighted_mean_of_the_spheres():
    """A roll moment M shifts the centre of pressure sideways by M / W (the body's weight W)."""
    moment = 0.01 * WEIGHT
    states = run(np.array([0, 0, 0, moment, 0, 0]), 0.2)
    centre = np.array([0.035, 0.0])  # the box's centre of mass over the sole
    polygon = tiny_scene()[2].polygons[0]
    expected = edge_margins(polygon, centre - [0.0, moment / WEIGHT]).min()
    assert states[-1, 0, MARGIN] == pytest.approx(expected, abs=5e-4)


def test_a_twisted_sole_lifts_an_edge():
    """A roll moment beyond what the narrow edge can carry (W times 25 mm) tips the sole onto an edge."""
    states = run(np.array([0, 0, 0, 0.035 * WEIGHT, 0, 0]), 0.05)
    assert lift_onset(states).any()
    assert states[:, 0, MARGIN].min() <= LIFT_MARGIN


@pytest.mark.parametrize("push", [0.5, 0.99])
def test_a_sole_pushed_inside_the_friction_cone_sticks(push):
    """A sticking soft contact creeps, far below the slip speed."""
    states = run(np.array([push * MU * WEIGHT, 0, 0, 0, 0, 0]), 0.2)
    assert not slip_onset(states).any()
    assert states[:, 0, SPEED].max() < 0.1 * SLIP_SPEED
    assert states[-1, 0, CONE] == pytest.approx(push, rel=1e-3)


def test_a_sole_pushed_beyond_the_friction_cone_slides():
    states = run(np.array([1.05 * MU * WEIGHT, 0, 0, 0, 0, 0]), 0.05)
    onset = slip_onset(states)[:, 0]
    assert onset.any()
    assert states[np.argmax(onset):, 0, CONE].min() >= 1.0 - 1e-3 or states[-1, 0, SPEED] > SLIP_SPEED
    assert states[-1, 0, SPEED] > SLIP_SPEED


def test_soles_of_different_sizes_share_one_edge_table():
    """A three-sphere sole beside a four-sphere one: the triangle's rows are padded with its first
    edge, so each sole's least margin over its rows is its polygon's."""
    feet = [((0.0, 0.0), (0.1, 0.0), (0.0, 0.05)), CORNERS]
    bodies = "".join(
        f'<body name="f{k}" pos="{k} 0 0.1"><freejoint/>'
        + "".join(f'<geom type="sphere" size="0.005" pos="{x} {y} 0"/>' for x, y in spheres) + "</body>"
        for k, spheres in enumerate(feet))
    model = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{bodies}</worldbody></mujoco>")
    soles = Soles.of(model, (1, 2), MU)
    assert soles.edges.shape == (2, 4, 4) and [len(p) for p in soles.polygons] == [3, 4]
    assert set(soles.foot_index.tolist()) == {0, 1} and np.bincount(soles.foot_index).tolist() == [3, 4]
    rng = np.random.default_rng(0)
    for k, polygon in enumerate(soles.polygons):
        for point in rng.uniform(-0.1, 0.15, (20, 2)):
            rows = soles.edges[k]
            margins = np.einsum("ij,ij->i", rows[:, 2:], rows[:, :2] - point)
            assert margins.min() == pytest.approx(edge_margins(polygon, point).min(), abs=1e-15)
