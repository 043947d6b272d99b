"""Post-impact CoM velocity inside the capture region (constraints/capture_constraint.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from whole_body_states import NORMAL, approach_velocity, robot, standing_states, upright, wall_ahead

from impactqp.constraints import ControlCycle, ExpectedImpact
from impactqp.constraints.capture_constraint import CaptureRegionLimit
from impactqp.constraints.impact_model import ActivationRule
from impactqp.controller.model.capture import capture_region, post_impact_com_velocity
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.humanoid_stance import support_polygon
from impactqp.controller.model.validation import BadInputError

H = 0.0025


@settings(max_examples=15, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 4.0), st.integers(0, 2**31))
def test_rows_hold_exactly_when_the_post_impact_com_velocity_is_capturable(state, method, speed, seed):
    """C dv <= u  <=>  capture.py's post-impact CoM velocity at v' = v + dv h lies in the
    capture region; each row is omega times the region's margin, over h."""
    _, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    terms = model.terms(q, v)
    polygon = support_polygon(model, q)
    limit = CaptureRegionLimit(ExpectedImpact(wall_ahead(q), method, rule=ActivationRule(always_active=True), held_contacts=True), polygon)
    rows = limit.compute(terms, ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    dv = np.random.default_rng(seed).normal(scale=200.0, size=model.nv)
    v_next = v + dv * H
    base = model.terms(q)
    dc_plus = post_impact_com_velocity(base, method, NORMAL, base.J @ v_next, base.Jcom @ v_next)
    region = capture_region(polygon, terms.com)
    np.testing.assert_allclose(rows.upper - rows.C @ dv, region.omega * region.margins(dc_plus) / H, atol=1e-6 / H)
    assert np.all(rows.lower == -np.inf)


def test_rows_are_unbounded_while_no_impact_is_coming():
    model = robot()
    q = model.terms(upright()).q
    limit = CaptureRegionLimit(ExpectedImpact(wall_ahead(q, 0.8), held_contacts=True), np.array([[0, 0], [1, 0], [0, 1.0]]))
    rows = limit.compute(model.terms(q), ControlCycle(0.001, np.full(model.nv, -1.0), np.full(model.nv, 1.0), H))
    assert limit.rows == 3 and np.all(rows.upper == np.inf)


def test_an_impact_without_held_contacts_has_no_capture_region():
    q = upright()
    with pytest.raises(BadInputError):
        CaptureRegionLimit(ExpectedImpact(wall_ahead(q, 0.8)), np.array([[0, 0], [1, 0], [0, 1.0]]))
