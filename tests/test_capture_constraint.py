"""Post-impact CoM velocity inside the capture region (constraints/capture_constraint.py)."""

import numpy as np
import pytest
from scipy.optimize import linprog
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from whole_body_states import NORMAL, approach_velocity, robot, standing_states, upright, vertex_impulses, wall_ahead

from impactqp.constraints import ControlCycle, ExpectedImpact
from impactqp.constraints.capture_constraint import CaptureRegionLimit, EdgeCaptureRegionLimit
from impactqp.constraints.impact_model import ActivationRule
from impactqp.controller.model.capture import capture_region, post_impact_com_velocity
from impactqp.controller.model.friction_pyramid import FrictionRows, held_response_maps, pyramid_directions
from impactqp.controller.model.jump import held_impulse, jump_model
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


def edge_limit(q, method, mu, edges=4):
    rule = ActivationRule(always_active=True)
    impact = ExpectedImpact(wall_ahead(q), method, rule=rule, held_contacts=True, friction=FrictionRows(mu, edges))
    return EdgeCaptureRegionLimit(impact, support_polygon(robot(), q))


@settings(max_examples=10, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 4.0), st.floats(0.05, 1.0),
       st.integers(3, 6), st.integers(0, 2**31))
def test_edge_rows_hold_exactly_when_every_vertex_com_velocity_is_capturable(state, method, speed, mu, edges, seed):
    """Block i of C dv <= u is omega times the capture region's margin of the post-impact CoM
    velocity of the pyramid's edge i at v' = v + dv h: Jcom v' plus the total momentum's change
    over the mass, (iota_i + the feet's impulsive forces) / m (``jump.held_impulse``, the feet
    held), iota_i the impulse along d_i that ends compression (from W alone); the first block is
    the frictionless impulse's (``CaptureRegionLimit``)."""
    _, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    limit = edge_limit(q, method, mu, edges)
    rows = limit.compute(model.terms(q, v), ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    dv = np.random.default_rng(seed).normal(scale=200.0, size=model.nv)
    v_next = v + dv * H
    base = model.terms(q)
    v_minus = base.J @ v_next
    W = held_response_maps(jump_model(method), base, NORMAL, 0.0)[1]
    region = capture_region(support_polygon(model, q), base.com)
    block = len(region.b)
    assert limit.rows == block * (1 + edges)
    frictionless = post_impact_com_velocity(base, method, NORMAL, v_minus, base.Jcom @ v_next)
    jumps = [(iota + held_impulse(base, iota).reshape(-1, 6)[:, :3].sum(axis=0)) / base.mass
             for iota in vertex_impulses(W, v_minus, pyramid_directions(NORMAL, mu, edges))]
    slack = rows.upper - rows.C @ dv
    for i, dc_plus in enumerate([frictionless] + [base.Jcom @ v_next + jump for jump in jumps]):
        expected = region.omega * region.margins(dc_plus) / H
        np.testing.assert_allclose(slack[i * block:(i + 1) * block], expected, atol=1e-6 / H)
    assert np.all(rows.lower == -np.inf)


@settings(max_examples=8, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 4.0), st.floats(0.05, 1.0))
def test_without_friction_the_edge_rows_are_the_frictionless_rows_exactly(state, method, speed, mu):
    """mu = 0: no edge, the rows of CaptureRegionLimit bit for bit; mu > 0: its rows first."""
    _, q, v = state
    model = robot()
    terms = model.terms(q, v + approach_velocity(q, speed))
    cycle = ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H)
    rule = ActivationRule(always_active=True)
    today = CaptureRegionLimit(ExpectedImpact(wall_ahead(q), method, rule=rule, held_contacts=True), support_polygon(model, q))
    expected = today.compute(terms, cycle)
    for friction in (0.0, mu):
        rows = edge_limit(q, method, friction).compute(terms, cycle)
        assert np.array_equal(rows.C[:today.rows], expected.C) and np.array_equal(rows.upper[:today.rows], expected.upper)
    assert edge_limit(q, method, 0.0).rows == today.rows


@settings(max_examples=6, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 1.0), st.floats(0.05, 1.0))
def test_at_a_solution_of_the_edge_rows_every_vertex_com_velocity_is_capturable(state, method, speed, mu):
    """A dv that meets every row (a linear program's solution, |dv_i| <= 1e4): at v' = v + dv h
    the post-impact CoM velocity of the frictionless impulse and of each edge impulse (the
    momentum balance with the feet held) lies inside the capture region."""
    _, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    limit = edge_limit(q, method, mu)
    rows = limit.compute(model.terms(q, v), ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    solution = linprog(np.zeros(model.nv), A_ub=rows.C, b_ub=rows.upper, bounds=[(-1e4, 1e4)] * model.nv, method="highs")
    assume(solution.status == 0)
    v_next = v + solution.x * H
    base = model.terms(q)
    v_minus = base.J @ v_next
    W = held_response_maps(jump_model(method), base, NORMAL, 0.0)[1]
    region = capture_region(support_polygon(model, q), base.com)
    impulses = [predict_impulse(base, method, v_minus)] + list(vertex_impulses(W, v_minus, pyramid_directions(NORMAL, mu, 4)))
    for iota in impulses:
        dc_plus = base.Jcom @ v_next + (iota + held_impulse(base, iota).reshape(-1, 6)[:, :3].sum(axis=0)) / base.mass
        assert np.all(region.margins(dc_plus) >= -1e-7)


def predict_impulse(terms, method, v_minus):
    """The predictor's frictionless impulse for the contact velocity v- (``JumpModel.predict``)."""
    return jump_model(method).predict(terms, NORMAL, v_minus).impulse
