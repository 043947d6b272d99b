"""Closed-form highest feasible contact speed of a G1 stance (controller/model/humanoid_max_speed.py)."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.capture import capturable_speeds, capture_region, max_capturable_speed
from impactqp.controller.model.floating_base import FloatingBaseModel, predict
from impactqp.controller.model.humanoid_max_speed import (
    CRITERIA,
    IMPACT_DURATION,
    Setting,
    approach_direction,
    closed_form_max_speed,
    cone_step,
    joint_velocity_bound,
    sole_rows,
    standing_wrenches,
)
from impactqp.controller.model.humanoid_stance import STANCES, convex_hull, inside_polygon, stance_posture, support_polygon
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError

NORMAL = np.array([-1.0, 0.0, 0.0])
FOOT = ROBOTS["g1"].held_contacts[0]
SOLE, SOLE_DEPTH = convex_hull(FOOT.sole), FOOT.depth
vectors = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(lambda v: np.round(v, 6))  # no 1e-300 slopes


@pytest.fixture(scope="module")
def robot():
    return FloatingBaseModel()


@pytest.fixture(scope="module", params=["parallel", "staggered"])
def stance_q(request, robot):
    return stance_posture(robot, STANCES[request.param])


@settings(max_examples=80, deadline=None)
@given(vectors, vectors, st.floats(0.2, 2.0))
def test_cone_step_ends_on_the_cone_and_stays_inside_before(force0, force1, mu):
    force0 = force0.copy()
    force0[2] = np.linalg.norm(force0[:2]) / mu + abs(force0[2]) + 0.1  # inside the cone at s = 0
    s = cone_step(force0, force1, mu)
    for t in np.linspace(0.0, min(s, 1e3), 7)[:-1]:
        f = force0 + t * force1
        assert np.linalg.norm(f[:2]) <= mu * f[2] + 1e-9 * (1 + np.abs(f).sum())
    if math.isfinite(s):
        f = force0 + s * force1
        assert np.linalg.norm(f[:2]) == pytest.approx(mu * f[2], abs=1e-6 * (1 + np.abs(f).sum()))


@settings(max_examples=80, deadline=None)
@given(st.floats(-0.1, 0.15), st.floats(-0.05, 0.05), st.floats(0.1, 100.0), vectors)
def test_sole_rows_hold_exactly_when_a_point_force_lies_inside_the_sole(x, y, fz, tangent):
    """A force (t_x, t_y, fz) applied at the sole point (x, y): the rows are <= 0 iff (x, y) is in the sole."""
    f = np.array([tangent[0], tangent[1], fz])
    point = np.array([x, y, -SOLE_DEPTH])  # in the foot frame
    wrench = np.concatenate([f, np.cross(point, f)])
    inside = inside_polygon([x, y], SOLE)
    rows = sole_rows(SOLE, SOLE_DEPTH, wrench) / fz
    if inside > 1e-9:
        assert np.all(rows < 0.0)
    elif inside < -1e-9:
        assert np.any(rows > 0.0)


def test_the_bound_is_the_smallest_criterion_and_every_criterion_is_met_up_to_it(robot, stance_q):
    result = closed_form_max_speed(robot, stance_q, NORMAL)
    assert set(result.bounds) == set(CRITERIA)
    assert result.speed == min(b.speed for b in result.bounds.values())
    assert result.bounds[result.criterion].speed == result.speed
    assert 0.0 < result.speed < math.inf


def test_joint_velocity_bound_puts_the_worst_joint_at_its_limit(robot, stance_q):
    terms = robot.terms(stance_q)
    d = approach_direction(robot, terms, NORMAL)
    np.testing.assert_allclose(terms.J @ d, -NORMAL, atol=1e-9)
    dv = predict(terms, "classical", NORMAL, terms.J @ d).dv
    bound = joint_velocity_bound(robot, d, dv)
    s = bound.speed
    joints = slice(robot.base_nv, None)
    ratio = np.maximum(np.abs(s * d[joints]), np.abs(s * (d + dv)[joints])) / robot.dq_max
    assert ratio.max() == pytest.approx(1.0)
    assert robot.joint_names[int(np.argmax(ratio))] == bound.where


def test_standing_wrenches_carry_the_weight(robot, stance_q):
    terms = robot.terms(stance_q)
    w = standing_wrenches(robot, terms)
    assert w[2] + w[8] == pytest.approx(terms.mass * 9.81, rel=1e-6)
    assert w[2] > 0.0 and w[8] > 0.0


@pytest.mark.parametrize("method", ["classical", "crb"])
def test_foot_bounds_scale_with_the_contact_duration_and_the_rest_does_not(robot, stance_q, method):
    """F = T w + s lambda: doubling T doubles the foot bounds (both are homogeneous in (T, s))."""
    one = closed_form_max_speed(robot, stance_q, NORMAL, Setting(method))
    two = closed_form_max_speed(robot, stance_q, NORMAL, Setting(method, impact_duration=2 * IMPACT_DURATION))
    for criterion in ("foot_slip", "foot_lift"):
        assert two.bounds[criterion].speed == pytest.approx(2 * one.bounds[criterion].speed, rel=1e-9)
    for criterion in ("joint_velocity", "capture"):
        assert two.bounds[criterion].speed == pytest.approx(one.bounds[criterion].speed, rel=1e-12)


def test_more_friction_never_lowers_the_slip_bound(robot, stance_q):
    low = closed_form_max_speed(robot, stance_q, NORMAL, Setting(friction=0.5))
    high = closed_form_max_speed(robot, stance_q, NORMAL, replace(Setting(), friction=1.5))
    assert high.bounds["foot_slip"].speed >= low.bounds["foot_slip"].speed


def test_capture_bound_is_the_capture_modules(robot, stance_q):
    terms = robot.terms(stance_q)
    region = capture_region(support_polygon(robot, stance_q), terms.com)
    v1 = terms.J @ approach_direction(robot, terms, NORMAL)
    result = closed_form_max_speed(robot, stance_q, NORMAL)
    assert result.bounds["capture"].speed == pytest.approx(max_capturable_speed(terms, region, "crb", NORMAL, v1))
    edges = capturable_speeds(terms, region, "crb", NORMAL, v1)
    assert result.bounds["capture"].where == f"edge {int(np.argmin(edges))}"


def test_zero_friction_is_bad_input(robot, stance_q):
    with pytest.raises(BadInputError):
        closed_form_max_speed(robot, stance_q, NORMAL, Setting(friction=0.0))
