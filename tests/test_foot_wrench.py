"""The feet's wrenches at the impact's peak force in their friction cones and soles
(constraints/foot_wrench.py): the rows against the closed form's foot slip and lift, and against a
plain-numpy statement."""

import numpy as np
import pytest
from scipy.optimize import linprog
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from reference.foot_wrench import reference_foot_wrench_rows
from whole_body_states import (
    NORMAL, approach_velocity, controller, robot, stance, standing_states, upright, vertex_impulses, wall_ahead,
)

from impactqp.constraints import ControlCycle, ExpectedImpact, FootWrenchLimit
from impactqp.constraints.foot_wrench import EdgeFootWrenchLimit
from impactqp.constraints.impact_model import ActivationRule
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.friction_pyramid import FrictionRows, held_response_maps, pyramid_directions
from impactqp.controller.model.humanoid_stance import convex_hull, inside_polygon
from impactqp.controller.model.jump import jump_model, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.max_speed import (
    HAND_IMPACT_DURATION, Setting, approach_direction, closed_form_max_speed, standing_wrenches,
)
from impactqp.controller.model.validation import BadInputError

H = 0.0025


def limit_at(q, method, duration=HAND_IMPACT_DURATION):
    impact = ExpectedImpact(wall_ahead(q), method, rule=ActivationRule(always_active=True), held_contacts=True)
    return FootWrenchLimit(impact, robot(), q, duration)


def row_values(limit, q, v) -> np.ndarray:
    """e . F / m of every row at dv = 0 (<= 0 where it holds)."""
    model = robot()
    rows = limit.compute(model.terms(q, v), ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    return -rows.upper * H


@settings(max_examples=15, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.0, 2.0), st.integers(0, 2**31))
def test_kernel_rows_are_the_reference_rows(state, method, speed, seed):
    _, q, v = state
    v = v + approach_velocity(q, speed)
    limit = limit_at(q, method)
    model = robot()
    terms = model.terms(q, v)
    rows = limit.compute(terms, ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    C, upper = reference_foot_wrench_rows(limit, model, terms, H)
    np.testing.assert_allclose(rows.C, C, atol=1e-9 * np.abs(C).max())
    np.testing.assert_allclose(rows.upper, upper, atol=1e-9 * np.abs(upper).max())
    assert np.all(rows.lower == -np.inf)


@settings(max_examples=10, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.001, 0.02))
def test_rows_and_the_closed_form_give_the_same_highest_speed(state, method, duration):
    """Along the closed form's approach v = s d (the hand's arm alone, the body at rest): the slip
    rows hold exactly up to the closed form's foot-slip speed and the sole rows up to its foot-lift
    speed; at each of those speeds the binding row is tight (relative to the standing rows)."""
    _, q, _ = state
    model = robot()
    terms = model.terms(q)
    bounds = closed_form_max_speed(model, terms, NORMAL, Setting(method, impact_duration=duration)).bounds
    d = approach_direction(model, terms, NORMAL)
    limit = limit_at(q, method, duration)
    slip = np.array([label.startswith("slip") for label in limit.labels])
    scale = np.abs(row_values(limit, q, 0.0 * d)).max()
    for criterion, rows in (("foot_slip", slip), ("foot_lift", ~slip)):
        bound = bounds[criterion]
        assert np.isfinite(bound.speed)
        if bound.speed == 0.0:  # a posture that already fails it standing (its CoP out of a sole)
            assert np.any(row_values(limit, q, 0.0 * d)[rows] > 0.0)
            continue
        at = row_values(limit, q, bound.speed * d)[rows]
        assert abs(at.max()) <= 1e-9 * scale
        assert bound.where in np.array(limit.labels)[rows][int(np.argmax(at))]
        assert np.all(row_values(limit, q, (1.0 - 1e-6) * bound.speed * d)[rows] < 0.0)
        assert np.any(row_values(limit, q, (1.0 + 1e-6) * bound.speed * d)[rows] > 0.0)


@settings(max_examples=8, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 1.0), st.integers(3, 6))
def test_edge_rows_and_the_frictional_closed_form_give_the_same_highest_speed(state, method, mu, edges):
    """With the friction rows of mu (k edges), along the closed form's approach v = s d: every
    vertex's slip rows hold up to the frictional closed form's foot-slip speed and its sole rows up
    to its foot-lift speed (``friction_max_speed``, the smallest over the vertices), and at each of
    those speeds the binding row, of the vertex and foot it names, is tight."""
    _, q, _ = state
    model = robot()
    terms = model.terms(q)
    answer = frictional_max_speed(model, terms, NORMAL, np.zeros(3), Setting(method), FrictionRows(mu, edges))
    d = approach_direction(model, terms, NORMAL)
    impact = ExpectedImpact(wall_ahead(q), method, rule=ActivationRule(always_active=True), held_contacts=True,
                            friction=FrictionRows(mu, edges))
    limit = EdgeFootWrenchLimit(impact, model, q, HAND_IMPACT_DURATION)
    labels = np.array(limit.labels)
    slip = np.array(["slip" in label for label in labels])
    scale = np.abs(row_values(limit, q, 0.0 * d)).max()
    for criterion, rows in (("foot_slip", slip), ("foot_lift", ~slip)):
        bound = answer.max_speed.bounds[criterion]
        assert np.isfinite(bound.speed)
        if bound.speed == 0.0:  # a posture that already fails it standing
            assert np.any(row_values(limit, q, 0.0 * d)[rows] > 0.0)
            continue
        at = row_values(limit, q, bound.speed * d)[rows]
        assert abs(at.max()) <= 1e-9 * scale
        assert bound.where in labels[rows][int(np.argmax(at))]
        assert np.all(row_values(limit, q, (1.0 - 1e-6) * bound.speed * d)[rows] < 0.0)
        assert np.any(row_values(limit, q, (1.0 + 1e-6) * bound.speed * d)[rows] > 0.0)
    binding = answer.max_speed
    if binding.criterion in ("foot_slip", "foot_lift") and answer.block.startswith("edge"):
        at = row_values(limit, q, binding.speed * d)
        assert labels[int(np.argmax(at))].startswith(f"{answer.block}: ")


@settings(max_examples=15, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 3.0), st.integers(0, 2**31))
def test_a_row_holds_whenever_the_cone_and_the_sole_hold(state, method, speed, seed):
    """For any dv, a row of C dv <= u fails only if the predicted wrench leaves its friction cone
    or its sole (the slip row is the cone's supporting plane): rows computed from the closed form's
    wrenches (max_speed's cone and sole rows) at v' = v + dv h."""
    _, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    limit = limit_at(q, method)
    rows = limit.compute(model.terms(q, v), ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    dv = np.random.default_rng(seed).normal(scale=20.0, size=model.nv)
    value = (rows.C @ dv - rows.upper) * H  # e . F(v + dv h) / m
    at_next = row_values(limit, q, v + dv * H)  # the rows taken at v' itself: the cone and the sole exactly
    slip = np.array([label.startswith("slip") for label in limit.labels])
    np.testing.assert_allclose(value[~slip], at_next[~slip], atol=1e-9 * np.abs(at_next).max())
    assert np.all(value[slip] <= at_next[slip] + 1e-9 * np.abs(at_next).max())


def test_rows_are_unbounded_while_no_impact_is_coming():
    model = robot()
    q = upright()
    limit = FootWrenchLimit(ExpectedImpact(wall_ahead(q, 0.8), held_contacts=True), model, q, HAND_IMPACT_DURATION)
    rows = limit.compute(model.terms(q), ControlCycle(0.001, np.full(model.nv, -1.0), np.full(model.nv, 1.0), H))
    assert limit.rows == 10 and np.all(rows.upper == np.inf) and np.all(rows.C == 0.0)


def test_an_impact_without_held_contacts_or_a_duration_is_bad_input():
    q = upright()
    with pytest.raises(BadInputError):
        FootWrenchLimit(ExpectedImpact(wall_ahead(q, 0.8)), robot(), q, HAND_IMPACT_DURATION)
    with pytest.raises(BadInputError):
        FootWrenchLimit(ExpectedImpact(wall_ahead(q, 0.8), held_contacts=True), robot(), q, 0.0)


@settings(max_examples=10, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.0, 2.0), st.floats(0.05, 1.0), st.integers(3, 6))
def test_edge_rows_are_the_reference_rows_of_every_vertex(state, method, speed, mu, edges):
    """Block i: the plain-numpy rows with G the impulse map of the pyramid's edge i (the impulse
    along d_i that ends compression, from W alone, per unit v-); the first block the frictionless
    rows of FootWrenchLimit, bit for bit; without friction, those rows alone."""
    _, q, v = state
    v = v + approach_velocity(q, speed)
    model = robot()
    terms = model.terms(q, v)
    rule = ActivationRule(always_active=True)
    impact = ExpectedImpact(wall_ahead(q), method, rule=rule, held_contacts=True, friction=FrictionRows(mu, edges))
    limit = EdgeFootWrenchLimit(impact, model, q, HAND_IMPACT_DURATION)
    cycle = ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H)
    rows = limit.compute(terms, cycle)
    today = limit_at(q, method)
    expected = today.compute(terms, cycle)
    block = today.rows
    assert limit.rows == block * (1 + edges) and len(limit.labels) == limit.rows
    assert np.array_equal(rows.C[:block], expected.C) and np.array_equal(rows.upper[:block], expected.upper)
    W = held_response_maps(jump_model(method), terms, NORMAL, 0.0)[1]
    for i, d in enumerate(pyramid_directions(NORMAL, mu, edges)):
        G = np.outer(vertex_impulses(W, NORMAL, d[None])[0], NORMAL)  # iota_i = G v-, linear in n^T v-
        C, upper = reference_foot_wrench_rows(limit, model, terms, H, impulse_map=G)
        part = slice((i + 1) * block, (i + 2) * block)
        np.testing.assert_allclose(rows.C[part], C, atol=1e-9 * np.abs(C).max())
        np.testing.assert_allclose(rows.upper[part], upper, atol=1e-9 * np.abs(upper).max())
    no_friction = ExpectedImpact(wall_ahead(q), method, rule=rule, held_contacts=True)
    alone = EdgeFootWrenchLimit(no_friction, model, q, HAND_IMPACT_DURATION)
    assert alone.rows == block and np.array_equal(alone.compute(terms, cycle).upper, expected.upper)


@settings(max_examples=6, deadline=None)
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.05, 1.0), st.floats(0.05, 1.0))
def test_at_a_solution_of_the_edge_rows_every_vertex_wrench_is_in_its_cone_and_sole(state, method, speed, mu):
    """A dv that meets every row (a linear program's solution, |dv_i| <= 1e4): at v' = v + dv h
    each foot's wrench at the peak of the frictionless impulse and of each edge impulse is inside
    its cone and its sole: the plain-numpy rows at v' itself, the slip row the cone's supporting
    plane u . F_xy - mu F_z with u the direction of F_xy at v, as the rows take it (linear in dv;
    the cone itself, |F_xy| - mu F_z, only to first order where the direction turns)."""
    _, q, v = state
    model = robot()
    v = v + approach_velocity(q, speed)
    rule = ActivationRule(always_active=True)
    impact = ExpectedImpact(wall_ahead(q), method, rule=rule, held_contacts=True, friction=FrictionRows(mu))
    limit = EdgeFootWrenchLimit(impact, model, q, HAND_IMPACT_DURATION)
    rows = limit.compute(model.terms(q, v), ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H))
    solution = linprog(np.zeros(model.nv), A_ub=rows.C, b_ub=rows.upper, bounds=[(-1e4, 1e4)] * model.nv, method="highs")
    assume(solution.status == 0)
    terms = model.terms(q, v + solution.x * H)
    W = held_response_maps(jump_model(method), terms, NORMAL, 0.0)[1]
    maps = [None] + [np.outer(vertex_impulses(W, NORMAL, d[None])[0], NORMAL) for d in pyramid_directions(NORMAL, mu, 4)]
    for G in maps:
        _, upper = reference_foot_wrench_rows(limit, model, terms, H, impulse_map=G, slip_dq=v)
        values = -upper * H  # e . F / m at v'
        assert np.all(values <= 1e-7 * max(np.abs(values).max(), 1.0))


def test_on_the_step_the_raised_sole_s_wrench_stays_in_its_cone_and_sole_at_the_qp_solution():
    """The step stance (the left sole on a 10 cm step): the hand at 0.95 of the closed form's speed,
    asked for 2 m/s. The QP's solution dv binds a foot row, and at v' = v + dv h every foot's wrench
    at the peak, F_k = T w_k + lambda_k(J v') (the predictor's impulsive wrench and the least-norm
    wrenches carrying the weight, computed here without the constraint), stays in its friction
    cone and its centre of pressure, found from the moments about the sole, in its sole."""
    model = robot()
    q = stance("step")
    terms = model.terms(q)
    placements = model.frame_placements(q)
    contacts = model.description.held_contacts
    assert placements[contacts[0].frame].translation[2] == pytest.approx(0.10 + contacts[0].depth, abs=1e-3)
    bound = closed_form_max_speed(model, terms, NORMAL, Setting("crb")).speed
    v = approach_velocity(q, 0.95 * bound)
    limiter = controller("step", gap=0.02, speed=2.0)
    limiter.reset(q, v)
    command = limiter.step(q, v)
    assert command.status == "ok" and "foot_wrench[crb]" in command.active_constraints
    h = max(limiter.dt, float(np.max(model.ddq_max / model.dddq_max)))
    v_next = v + command.ddq * h
    impact = predict(model.terms(q, v_next), "crb", NORMAL, terms.J @ v_next)
    peak = HAND_IMPACT_DURATION * standing_wrenches(model, terms) + impact.held_impulse
    for k, contact in enumerate(contacts):
        R = placements[contact.frame].rotation
        f, tau = R.T @ peak[6 * k:6 * k + 3], R.T @ peak[6 * k + 3:6 * k + 6]
        assert np.hypot(f[0], f[1]) <= contact.friction * f[2] * (1.0 + 1e-6)
        tau_sole = tau + np.cross([0.0, 0.0, contact.depth], f)  # about the sole's point under the frame
        centre = np.array([-tau_sole[1], tau_sole[0]]) / f[2]
        assert inside_polygon(centre, convex_hull(contact.sole)) >= -1e-9
