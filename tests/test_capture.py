"""Zero-step capture region and post-impact CoM velocity (controller/model/capture.py)."""

import math

import numpy as np
import pytest
from conftest import unit_vectors
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.capture import (
    FLOOR_TOLERANCE,
    GRAVITY,
    capture_region,
    floor_support_polygon,
    support_capture_region,
    support_heights,
    com_jump_map,
    max_capturable_speed,
    post_impact_com_velocity,
    row_steps,
)
from impactqp.controller.model.jump import held_impulse, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import STANCES, convex_hull, inside_polygon, stance_posture, support_polygon
from impactqp.controller.model.validation import BadInputError

SQUARE = np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])
WALL = np.array([-1.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def standing():
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    return robot, q, robot.terms(q)


@settings(max_examples=60, deadline=None)
@given(v=st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=2), cx=st.floats(-0.09, 0.09),
       height=st.floats(0.3, 1.2))
def test_region_holds_exactly_the_velocities_whose_capture_point_is_in_the_polygon(v, cx, height):
    com = np.array([cx, 0.02, height])
    region = capture_region(SQUARE, com)
    assert region.omega == pytest.approx(math.sqrt(GRAVITY / height))
    xi = com[:2] + np.array(v) / region.omega
    margin = inside_polygon(xi, SQUARE)
    if abs(margin) > 1e-9:
        assert region.contains(v) == (margin > 0.0)
    # the margins are the capture point's distances to the edges (m)
    assert region.margins(v).min() == pytest.approx(margin, abs=1e-9)


def test_a_vertex_capture_point_is_on_the_boundary():
    com = np.array([0.0, 0.0, 0.8])
    region = capture_region(SQUARE, com)
    v = region.omega * (SQUARE[2] - com[:2])
    assert region.margins(v).min() == pytest.approx(0.0, abs=1e-12)


def test_bad_regions_are_refused():
    with pytest.raises(BadInputError):
        capture_region(SQUARE[:2], np.array([0.0, 0.0, 0.8]))
    with pytest.raises(BadInputError):
        capture_region(SQUARE, np.array([0.0, 0.0, -0.1]))


@settings(max_examples=20, deadline=None)
@given(impulse=st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3))
def test_com_jump_is_the_momentum_of_hand_and_feet_impulses(standing, impulse):
    _, _, terms = standing
    impulse = np.array(impulse)
    feet = held_impulse(terms, impulse)
    np.testing.assert_allclose(terms.mass * com_jump_map(terms) @ impulse, impulse + feet[:3] + feet[6:9], atol=1e-8)


@settings(max_examples=20, deadline=None)
@given(n=unit_vectors(), v=st.floats(0.01, 1.0), cr=st.floats(0.0, 1.0),
       dc=st.lists(st.floats(-0.1, 0.1), min_size=3, max_size=3))
def test_post_impact_com_velocity_adds_the_predicted_jump(standing, n, v, cr, dc):
    _, _, terms = standing
    for method in METHODS:
        impulse = predict(terms, method, n, -v * n, cr).impulse
        expected = np.array(dc) + com_jump_map(terms) @ impulse
        np.testing.assert_allclose(post_impact_com_velocity(terms, method, n, -v * n, dc, cr), expected)
    # the classical impulse's CoM jump is the classical prediction's own
    classical = predict(terms, "classical", n, -v * n, cr)
    np.testing.assert_allclose(com_jump_map(terms) @ classical.impulse, classical.com_jump, atol=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_max_capturable_speed_is_the_boundary(standing, method):
    robot, q, terms = standing
    region = capture_region(support_polygon(robot, q), terms.com)
    direction = np.array([1.0, 0.0, 0.0])
    s = max_capturable_speed(terms, region, method, WALL, direction)
    assert 0.0 < s < math.inf
    at = post_impact_com_velocity(terms, method, WALL, s * direction, np.zeros(3))
    beyond = post_impact_com_velocity(terms, method, WALL, 1.01 * s * direction, np.zeros(3))
    assert region.margins(at).min() == pytest.approx(0.0, abs=1e-9)
    assert region.contains(0.99 * at) and not region.contains(beyond)
    # the impulse scales with (1 + c_r): the speed limit with 1 / (1 + c_r)
    assert max_capturable_speed(terms, region, method, WALL, direction, 0.5) == pytest.approx(s / 1.5)


def test_a_robot_already_outside_its_region_captures_nothing(standing):
    robot, q, terms = standing
    region = capture_region(support_polygon(robot, q) + 1.0, terms.com)  # polygon far from the CoM
    assert max_capturable_speed(terms, region, "crb", WALL, np.array([1.0, 0.0, 0.0])) == 0.0


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5, allow_subnormal=False)), min_size=1, max_size=8))
def test_row_steps_bring_each_rising_row_to_zero(rows):
    """Each row's step puts it exactly at zero when it rises from a held row, is inf when it does
    not rise (or rises so slowly that the step overflows), 0 when the row already fails; every
    row holds for every s up to the smallest step."""
    offset, slope = np.array(rows).T
    steps = row_steps(offset, slope)
    for o, k, s in zip(offset, slope, steps):
        if o > 0.0:
            assert s == 0.0
        elif k > 0.0 and -o / np.finfo(float).max <= k:
            assert o + s * k == pytest.approx(0.0, abs=1e-9 * (1 + abs(o)))
        elif k > 0.0:  # a slope so small that -o / k overflows: no finite step reaches zero
            assert s == math.inf
        else:
            assert s == math.inf
    smallest = steps.min()
    if math.isfinite(smallest) and np.all(offset <= 0.0):
        for t in np.linspace(0.0, smallest, 7):
            assert np.all(offset + t * slope <= 1e-9 * (1 + np.abs(offset)))


# ---------------------------------------------------------------- non-coplanar soles (a step)
@pytest.fixture(scope="module")
def on_step():
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["step"])
    return robot, q, robot.terms(q)


@pytest.mark.parametrize("name", [name for name, stance in STANCES.items() if stance.coplanar])
def test_coplanar_soles_give_the_support_polygon_s_region(name):
    """On the floor every corner projects onto itself (k = 1): the region is the one of the soles'
    hull, to 1e-9."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES[name])
    com = robot.terms(q).com
    np.testing.assert_array_equal(support_heights(robot, q), 0.0)
    old, new = capture_region(support_polygon(robot, q), com), support_capture_region(robot, q, com)
    np.testing.assert_allclose(new.A, old.A, atol=1e-9)
    np.testing.assert_allclose(new.b, old.b, atol=1e-9)
    assert new.omega == old.omega


def test_the_step_s_heights_are_read_from_the_posture(on_step):
    robot, q, _ = on_step
    np.testing.assert_allclose(support_heights(robot, q), STANCES["step"].heights, atol=1e-3)
    lifted = q.copy()
    lifted[2] += FLOOR_TOLERANCE / 2  # half the tolerance up: both soles still count as on their surfaces
    assert support_heights(robot, lifted)[1] == 0.0


@settings(max_examples=25, deadline=None)
@given(weights=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8).filter(lambda w: sum(w) > 1e-3),
       offset=st.lists(st.floats(-0.05, 0.05), min_size=2, max_size=2))
def test_forces_aimed_at_the_com_put_the_floor_zmp_in_the_projected_polygon(on_step, weights, offset):
    """The pendulum of the module docstring, from first principles: forces f_i = l_i (c - p_i) from
    the step stance's corners (p_i on their surfaces) carrying the weight have no moment about c
    and give c''_xy = omega^2 (c_xy - z), omega^2 = g / c_z, with z on the floor inside the
    projected polygon; and each such force is inside its sole's friction cone."""
    robot, q, terms = on_step
    com = terms.com + np.array([*offset, 0.0])
    heights = np.repeat(STANCES["step"].heights, 4)
    corners = np.column_stack([robot.sole_corners(q)[:, :2], heights])
    share = np.array(weights) / sum(weights)  # each corner's share of the weight
    forces = (share * terms.mass * GRAVITY / (com[2] - heights))[:, None] * (com - corners)
    np.testing.assert_allclose(forces.sum(axis=0)[2], terms.mass * GRAVITY)
    np.testing.assert_allclose(np.cross(corners - com, forces).sum(axis=0), 0.0, atol=1e-9)
    acceleration = forces.sum(axis=0)[:2] / terms.mass
    omega2 = GRAVITY / com[2]
    zmp = com[:2] - acceleration / omega2
    assert inside_polygon(zmp, floor_support_polygon(robot, q, com)) >= -1e-4  # the soles stand within 0.1 mm of their surfaces
    mu = [c.friction for c in robot.description.held_contacts for _ in range(4)]
    assert np.all(np.linalg.norm(forces[:, :2], axis=1) <= np.array(mu) * forces[:, 2])


@settings(max_examples=40, deadline=None)
@given(offset=st.lists(st.floats(-0.3, 0.3), min_size=2, max_size=2))
def test_at_rest_the_region_holds_the_com_exactly_over_the_soles_hull(on_step, offset):
    """A CoM at rest is capturable iff it stands over the convex hull of the soles' corners (static
    equilibrium): the projection from the CoM scales the corners about it."""
    robot, q, terms = on_step
    com = terms.com + np.array([*offset, 0.0])
    over = inside_polygon(com, support_polygon(robot, q))
    margin = support_capture_region(robot, q, com).margins(np.zeros(2)).min()
    if abs(over) > 1e-6:
        assert (margin > 0.0) == (over > 0.0)


def test_the_raised_sole_s_corners_project_away_from_the_com(on_step):
    """k = c_z / (c_z - h) > 1 for the raised sole: its corners move away from the CoM on the floor,
    the floor sole's stay (checked on the polygon's vertices)."""
    robot, q, terms = on_step
    com = terms.com
    corners = robot.sole_corners(q)[:, :2]
    k = com[2] / (com[2] - STANCES["step"].heights[0])
    expected = np.vstack([com[:2] + k * (corners[:4] - com[:2]), corners[4:]])
    np.testing.assert_allclose(floor_support_polygon(robot, q, com), convex_hull(expected), atol=1e-3 * k)
    with pytest.raises(BadInputError):
        floor_support_polygon(robot, q, np.array([*com[:2], 0.05]))  # a CoM below the step
