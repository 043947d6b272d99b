"""Impact-aware joint velocity rows of the standing humanoid (constraints/floating_post_impact.py)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from whole_body_states import NORMAL, approach_velocity, robot, standing_states, upright, wall_ahead

from impactqp.constraints import ControlCycle
from impactqp.constraints.floating_impact import FloatingExpectedImpact
from impactqp.constraints.floating_post_impact import FloatingPostImpactVelocityLimit
from impactqp.controller.model.floating_base import METHODS, predict

H = 0.0025


@settings(max_examples=15, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 3.0), st.integers(0, 2**31))
def test_rows_hold_exactly_when_the_predicted_post_impact_joint_velocities_are_in_the_limits(
    state, method, speed, seed
):
    """C dv <= u and >= l  <=>  |S (v' + dv_jump(v'))| <= dq_max with v' = v + dv h, dv_jump
    the predictor's jump at v- = J v'."""
    name, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    terms = model.terms(q, v)
    limit = FloatingPostImpactVelocityLimit(FloatingExpectedImpact(wall_ahead(q), method, always_active=True), model.dq_max)
    rows = limit.compute(terms, ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    dv = np.random.default_rng(seed).normal(scale=2000.0, size=model.nv)
    v_next = v + dv * H
    post = (v_next + predict(model.base.terms(q), method, NORMAL, terms.J @ v_next).dv)[model.base_nv:]
    inside_rows = np.all(rows.C @ dv <= rows.upper + 1e-9) and np.all(rows.C @ dv >= rows.lower - 1e-9)
    margin = np.min(model.dq_max - np.abs(post))
    if abs(margin) > 1e-6:
        assert inside_rows == (margin > 0)
    np.testing.assert_allclose(rows.C @ dv - rows.upper, (post - model.dq_max) / H, atol=1e-6 / H)


def test_rows_are_unbounded_while_no_impact_is_coming():
    q = robot().terms(upright()).q
    model = robot()
    limit = FloatingPostImpactVelocityLimit(FloatingExpectedImpact(wall_ahead(q, 0.8)), model.dq_max)
    rows = limit.compute(model.terms(q), ControlCycle(0.001, np.full(model.nv, -1.0), np.full(model.nv, 1.0), H))
    assert np.all(rows.lower == -np.inf) and np.all(rows.upper == np.inf)
