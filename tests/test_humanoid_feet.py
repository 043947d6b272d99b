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
    sole_state,
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


def run(wrench, seconds, settle=0.2):
    """Stand for ``settle`` s, then apply ``wrench`` (force, moment at the body's centre of mass):
    the sole states after the settling, worst per 1 ms."""
    model, data, soles = tiny_scene()
    states, step = [], None
    for k in range(int(round((settle + seconds) / model.opt.timestep))):
        data.xfrc_applied[1] = wrench if k * model.opt.timestep >= settle else 0.0
        mujoco.mj_step(model, data)
        now = sole_state(model, data, soles)
        step = now if step is None else worst(step, now)
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
