"""Standing postures of the G1 (controller/model/humanoid_stance.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.held_contact_description import cross2
from impactqp.controller.model.humanoid_stance import (
    STANCES,
    convex_hull,
    edge_margins,
    inside_polygon,
    stance_posture,
    support_polygon,
)
from impactqp.controller.model.robot_description import Stance
from impactqp.controller.model.validation import BadInputError


@pytest.fixture(scope="module")
def humanoid() -> RobotModel:
    return RobotModel("g1")


@pytest.mark.parametrize("name", list(STANCES))
def test_stance_stands_flat_with_the_com_over_the_feet_and_the_hand_on_target(humanoid, name):
    stance = STANCES[name]
    q = stance_posture(humanoid, stance)
    heights = [stance.height(k) for k in range(len(stance.feet))]
    np.testing.assert_allclose(humanoid.sole_corners(q)[:, 2], np.repeat(heights, 4), atol=1e-4)
    placements = humanoid.frame_placements(q)
    for foot, xy, height in zip(humanoid.description.held_contacts, stance.feet, heights, strict=True):
        np.testing.assert_allclose(placements[foot.frame].translation, [*xy, height + foot.depth], atol=1e-3)
        np.testing.assert_allclose(placements[foot.frame].rotation, np.eye(3), atol=1e-3)
    contact = humanoid.contact_frame_name
    np.testing.assert_allclose(placements[contact].translation, stance.hand, atol=5e-3)
    assert placements[contact].rotation[0, 0] > 0.99  # forearm towards the wall (+x)
    assert inside_polygon(humanoid.terms(q).com, support_polygon(humanoid, q)) > 0.03
    joints = q[humanoid.base_nq:]
    assert np.all((joints >= humanoid.q_min) & (joints <= humanoid.q_max))


def test_the_step_stance_puts_the_left_sole_on_a_raised_surface(humanoid):
    """The step stance's left sole stands on its 10 cm step and the right one on the floor."""
    stance = STANCES["step"]
    assert stance.heights == (0.10, 0.0) and not stance.coplanar
    corners = humanoid.sole_corners(stance_posture(humanoid, stance))
    np.testing.assert_allclose(corners[:4, 2], 0.10, atol=1e-4)
    np.testing.assert_allclose(corners[4:, 2], 0.0, atol=1e-4)


def test_an_unreachable_hand_is_bad_input(humanoid):
    with pytest.raises(BadInputError):
        stance_posture(humanoid, Stance("far", ((0.0, 0.12), (0.0, -0.12)), (1.5, -0.2, 0.95)))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=3, max_size=30))
def test_convex_hull_holds_every_point_and_is_made_of_them(points):
    points = np.array(points)
    hull = convex_hull(points)
    if len(hull) < 3 or abs(cross2(hull[1] - hull[0], hull[2] - hull[0])) < 1e-9:
        return  # (nearly) collinear points have no interior
    for p in points:
        assert inside_polygon(p, hull) >= -1e-9
    assert all(any(np.allclose(v, p) for p in points) for v in hull)
    assert inside_polygon(hull.mean(axis=0), hull) > 0.0
    assert inside_polygon(hull.max(axis=0) + 1.0, hull) < 0.0


def test_edge_margins_of_a_square():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    np.testing.assert_allclose(edge_margins(square, np.array([0.25, 0.5])), [0.5, 0.75, 0.5, 0.25])
    assert edge_margins(square, np.array([1.5, 0.5])).min() == pytest.approx(-0.5)
    assert inside_polygon([1.5, 0.5], square) == pytest.approx(-0.5)
