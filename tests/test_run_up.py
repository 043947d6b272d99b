"""The run-up of a standing robot's QP approach (controller/model/run_up.py)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from whole_body_states import NORMAL, robot, stance

from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.run_up import LIMIT_MARGIN, TRACKING_TOLERANCE, run_up_distance, run_up_posture
from impactqp.controller.model.validation import BadInputError


@given(st.floats(0.05, 3.0), st.floats(5.0, 100.0))
def test_the_first_order_hand_reaches_the_speed_within_the_tolerance_over_the_distance(speed, gain):
    """Euler steps of dv/dt = k (v* - v) from rest: when the hand has covered D, v >= (1 - tol) v*
    (and not long before: at 0.9 D it is still short)."""
    distance = run_up_distance(speed, gain)
    dt = 1e-4 / gain
    v, x, speed_at = 0.0, 0.0, {}
    while x < distance:
        v += gain * (speed - v) * dt
        x += v * dt
        if x >= 0.9 * distance and "early" not in speed_at:
            speed_at["early"] = v
    assert v >= (1.0 - TRACKING_TOLERANCE) * speed * (1 - 1e-3)
    assert speed_at["early"] < (1.0 - TRACKING_TOLERANCE) * speed


@settings(max_examples=5, deadline=None)
@given(st.sampled_from(sorted(STANCES)), st.floats(0.01, 0.12))
def test_the_run_up_moves_the_hand_back_along_the_normal_and_the_arm_alone(name, distance):
    model = robot()
    q = stance(name)
    start = run_up_posture(model, q, NORMAL, distance)
    moved = model.terms(q).contact_point - model.terms(start).contact_point
    assert moved @ -NORMAL == pytest.approx(distance, abs=1e-3)
    assert np.linalg.norm(moved - (moved @ NORMAL) * NORMAL) < 2e-3
    arm = [model.base_nq + model.joint_index(j) for j in model.description.contact.joints]
    body = np.setdiff1d(np.arange(model.nq), arm)
    np.testing.assert_array_equal(start[body], q[body])


def test_a_run_up_longer_than_the_arm_stops_inside_the_joint_limits():
    model = robot()
    start = run_up_posture(model, stance("parallel"), NORMAL, 1.0)
    joints = start[model.base_nq:]
    assert np.all(joints >= model.q_min + LIMIT_MARGIN) and np.all(joints <= model.q_max - LIMIT_MARGIN)
    assert math.dist(model.terms(start).contact_point, model.terms(stance("parallel")).contact_point) < 1.0


def test_a_run_up_needs_a_positive_gain():
    with pytest.raises(BadInputError):
        run_up_distance(1.0, 0.0)
