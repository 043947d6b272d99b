"""The robust friction rows (controller/model/friction_pyramid.py) and their stacking in the
impact-aware constraints: identities from first principles (docs/frictional-impacts.md)."""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from reference.friction_pyramid import reference_edge_matrices, reference_slip_edges
from scipy.optimize import linprog

from conftest import JOINTS, random_state
from whole_body_states import approach_velocity, standing_states, vertex_impulses, wall_ahead
from whole_body_states import robot as whole_body_robot
from impactqp.constraints import ActivationRule, ControlCycle, ExpectedImpact, ImpulsiveTorqueLimit, PostImpactVelocityLimit
from impactqp.controller.model.friction_pyramid import (
    EDGE_GUARD,
    held_response_maps,
    SLIP_SECTOR,
    SLIP_SPEED,
    FrictionRows,
    edge_matrices_into,
    pyramid_directions,
    slip_edges_into,
)
from impactqp.controller.model.frictional_impact import frictional_impulse
from impactqp.controller.model.jump import crb_inverse_inertia, jump_model
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.validation import BadInputError

DT = 0.001
DURATION = 0.015
SEEDS = st.integers(0, 2**32 - 1)
NORMAL = np.array([-1.0, 0.0, 0.0])
MODELS = ["crb", "gm", "classical"]


def wide_cycle(robot):
    """A cycle whose reachable accelerations are wide enough that no row is relaxed."""
    c = ControlCycle.after(np.zeros(JOINTS), DT, 1e6 * robot.ddq_max, 1e9 * robot.dddq_max)
    horizon = ControlCycle.after(np.zeros(JOINTS), DT, robot.ddq_max, robot.dddq_max).horizon
    return ControlCycle(DT, c.acceleration_lower, c.acceleration_upper, horizon)


def raw_rows(constraint, terms, c):
    C, lower, upper = np.empty((constraint.rows, JOINTS)), np.empty(constraint.rows), np.empty(constraint.rows)
    constraint.compute_into(terms, c, C, lower, upper)
    return C, lower, upper


def chebyshev_centre(rows) -> tuple[np.ndarray, float]:
    """The centre and radius of the largest ball inside lower <= C ddq <= upper (an LP; the
    ball is bounded to 20 rad/s^2 so that the LP is bounded)."""
    C = np.vstack([C for C, _, _ in rows])
    lower, upper = np.concatenate([lo for _, lo, _ in rows]), np.concatenate([hi for _, _, hi in rows])
    finite_up, finite_low = np.isfinite(upper), np.isfinite(lower)
    norms = np.linalg.norm(C, axis=1)
    A = np.vstack([np.column_stack([C[finite_up], norms[finite_up]]), np.column_stack([-C[finite_low], norms[finite_low]])])
    b = np.concatenate([upper[finite_up], -lower[finite_low]])
    objective = np.zeros(C.shape[1] + 1)
    objective[-1] = -1.0
    result = linprog(objective, A_ub=A, b_ub=b, bounds=[(-20.0, 20.0)] * C.shape[1] + [(0.0, 20.0)], method="highs")
    return (result.x[:-1], result.x[-1]) if result.status == 0 else (np.zeros(C.shape[1]), 0.0)


def impact(terms, model, friction, restitution=0.3, edges=4, mode="pyramid"):
    surface = Surface(terms.contact_point - 0.05 * NORMAL, NORMAL)
    return ExpectedImpact(surface, model, restitution, ActivationRule(always_active=True), friction=FrictionRows(friction, edges, mode))


def response(terms, model):
    """(K, W) from their definitions: J+ W with W_crb (20) or W_gm (22); M^-1 J^T with W_gm."""
    if model == "crb":
        W = crb_inverse_inertia(terms)
        return np.linalg.pinv(terms.J) @ W, W
    W = terms.J @ np.linalg.inv(terms.M) @ terms.J.T
    K = np.linalg.pinv(terms.J) @ W if model == "gm" else np.linalg.solve(terms.M, terms.J.T)
    return K, W


def edge_impulse(W, direction, v, restitution):
    """The impulse along d that ends compression, times 1 + c_r: p d with n^T (v + W p d) = 0,
    p = -n.v / (n^T W d), its denominator guarded (at least kappa n^T W n)."""
    return -(1.0 + restitution) * (NORMAL @ v) / max(NORMAL @ W @ direction, EDGE_GUARD * (NORMAL @ W @ NORMAL)) * direction


@pytest.mark.parametrize("model", [*MODELS, "classical_normal"])
@pytest.mark.parametrize("rows", [FrictionRows(), FrictionRows(0.0, 9, "slip")])
def test_zero_friction_gives_todays_rows_bit_identically(robot, model, rows):
    rng = np.random.default_rng(7)
    terms, c = random_state(robot, rng), wide_cycle(robot)
    surface = Surface(terms.contact_point - 0.05 * NORMAL, NORMAL)
    today = ExpectedImpact(surface, model, 0.3, ActivationRule(always_active=True))
    zero = ExpectedImpact(surface, model, 0.3, ActivationRule(always_active=True), friction=rows)
    for kind in (lambda i: PostImpactVelocityLimit(i, robot.dq_max), lambda i: ImpulsiveTorqueLimit(i, robot.tau_max, robot.dq_max)):
        a, b = kind(today), kind(zero)
        assert a.rows == b.rows == JOINTS
        for x, y in zip(raw_rows(a, terms, c), raw_rows(b, terms, c)):
            assert np.array_equal(x, y)


@given(st.floats(0.0, 2.0), st.integers(3, 16), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_the_pyramid_edges_are_evenly_spaced_and_circumscribe_the_cone(mu, k, x, y, z):
    normal = np.array([x, y, z])
    if np.linalg.norm(normal) < 1e-3:
        normal = NORMAL
    normal = normal / np.linalg.norm(normal)
    directions = pyramid_directions(normal, mu, k)
    tangents = directions - normal
    assert np.allclose(tangents @ normal, 0.0, atol=1e-12)
    assert np.allclose(np.linalg.norm(tangents, axis=1), mu / math.cos(math.pi / k), atol=1e-12)
    unit = pyramid_directions(normal, 1.0, k) - normal
    cosines = np.sum(unit * np.roll(unit, -1, axis=0), axis=1) / np.sum(unit * unit, axis=1)
    assert np.allclose(cosines, math.cos(2.0 * math.pi / k), atol=1e-9)
    # circumscribed: the midpoint of each side of the section's polygon lies on the cone's circle
    midpoints = (tangents + np.roll(tangents, -1, axis=0)) / 2.0
    assert np.allclose(np.linalg.norm(midpoints, axis=1), mu, atol=1e-12)


@settings(max_examples=30)
@given(SEEDS, st.sampled_from(MODELS), st.floats(0.01, 2.0), st.integers(3, 16), st.floats(0.0, 1.0))
def test_each_edge_block_is_the_post_impact_velocity_and_torque_of_its_edge_impulse(robot, seed, model, mu, k, c_r):
    """Block i of the rows maps dq- to dq- + K iota_i (velocity) and to s J^T iota_i (torque),
    iota_i the edge impulse of the definition (``edge_impulse``), K and W the predictor's."""
    rng = np.random.default_rng(seed)
    terms, c = random_state(robot, rng), wide_cycle(robot)
    expected = impact(terms, model, mu, c_r, k)
    velocity = PostImpactVelocityLimit(expected, robot.dq_max)
    torque = ImpulsiveTorqueLimit(expected, robot.tau_max, robot.dq_max, DURATION)
    assert velocity.rows == torque.rows == JOINTS * (k + 1)
    C_velocity, C_torque = raw_rows(velocity, terms, c)[0], raw_rows(torque, terms, c)[0]
    K, W = response(terms, model)
    for dq_pre in rng.uniform(-1.0, 1.0, (5, JOINTS)):
        v = terms.J @ dq_pre
        for i, d in enumerate(pyramid_directions(NORMAL, mu, k)):
            iota = edge_impulse(W, d, v, c_r)
            block = slice((i + 1) * JOINTS, (i + 2) * JOINTS)
            np.testing.assert_allclose(C_velocity[block] @ dq_pre, dq_pre + K @ iota, rtol=1e-8, atol=1e-8)
            np.testing.assert_allclose(C_torque[block] @ dq_pre, torque.row_scale * (terms.J.T @ iota), rtol=1e-8, atol=1e-8)


@settings(max_examples=60)
@given(SEEDS, st.integers(1, 16), st.floats(0.0, 1.0), st.floats(0.0, 3.0), st.booleans())
def test_compiled_edge_kernels_equal_the_numpy_reference(seed, edges, c_r, approach, classical):
    """Random J, M^-1 and W (the guard binds for some edges: W's tangential coupling is drawn up to
    twice its normal entry), random directions, K = M^-1 J^T (classical) or J^T (J J^T)^-1 W;
    the preview's edges at random contact velocities whose normal approach (``approach`` times
    the tangential speed, and slides below the slip threshold) makes the slip certain or not."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(3, JOINTS))
    JJt_inv = np.linalg.inv(J @ J.T)
    B = rng.normal(size=(JOINTS, JOINTS))
    M_inv = B @ B.T + 0.1 * np.eye(JOINTS)
    L = rng.normal(size=(3, 3))
    W = L @ L.T + 0.1 * np.eye(3)
    K = M_inv @ J.T if classical else J.T @ JJt_inv @ W
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    directions = normal + rng.uniform(0.0, 2.0) * rng.normal(size=(edges, 3))
    out = np.empty((2, edges, JOINTS, JOINTS))
    edge_matrices_into(J, JJt_inv, M_inv if classical else np.empty((0, 0)), W, directions, normal, c_r, out)
    reference = reference_edge_matrices(J, K, W, normal, directions, c_r)
    np.testing.assert_allclose(out[0], reference.jump, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(out[1], reference.torque, rtol=1e-10, atol=1e-10)
    tangent = np.cross(normal, rng.normal(size=3))
    speed = rng.choice([0.5 * SLIP_SPEED, rng.uniform(SLIP_SPEED, 1.0)])
    velocity = speed * tangent / np.linalg.norm(tangent) - approach * speed * normal
    mu, uncertain = rng.uniform(0.0, 1.0), pyramid_directions(normal, 0.5, 3)
    preview = uncertain.copy()
    slip_edges_into(velocity, W, normal, mu, c_r, preview)
    np.testing.assert_allclose(preview, reference_slip_edges(velocity, W, normal, mu, c_r, uncertain), rtol=1e-12, atol=1e-12)


@settings(max_examples=25)
@given(SEEDS, st.sampled_from(MODELS), st.floats(0.05, 1.5), st.integers(3, 8), st.floats(0.0, 1.0))
def test_when_every_row_holds_every_impulse_of_the_pyramid_section_keeps_the_limits(robot, seed, model, mu, k, c_r):
    """The convexity argument, numerically: at a pre-impact velocity dq- = dq + h ddq whose rows
    hold, any convex combination of the frictionless and the edge impulses (the edge ones span
    the pyramid's cone, which holds the friction cone) gives a post-impact velocity and an
    impulsive torque inside the limits."""
    rng = np.random.default_rng(seed)
    terms, c = random_state(robot, rng, speed=0.05), wide_cycle(robot)
    expected = impact(terms, model, mu, c_r, k)
    velocity = PostImpactVelocityLimit(expected, robot.dq_max)
    torque = ImpulsiveTorqueLimit(expected, robot.tau_max, robot.dq_max, DURATION)
    rows = [raw_rows(velocity, terms, c), raw_rows(torque, terms, c)]
    K, W = response(terms, model)
    own = expected.matrices(terms).impulse_map  # the predictor's own impulse map G
    directions = pyramid_directions(NORMAL, mu, k)
    frame_tangents = np.eye(3) - np.outer(NORMAL, NORMAL)
    centre, radius = chebyshev_centre(rows)
    assume(radius > 1e-3)  # the rows leave room (a fast state with a wide pyramid may not)
    held = 0
    for step in rng.normal(size=(40, JOINTS)):
        ddq = centre + 0.99 * radius * rng.uniform() * step / np.linalg.norm(step)  # inside the rows
        assert all(np.all(C @ ddq >= lo - 1e-9) and np.all(C @ ddq <= hi + 1e-9) for C, lo, hi in rows)
        held += 1
        pre = terms.dq + c.horizon * ddq
        v = terms.J @ pre
        impulses = [own @ v] + [edge_impulse(W, d, v, c_r) for d in directions]
        weights = rng.dirichlet(np.ones(len(impulses)))
        iota = weights @ np.array(impulses)
        assert np.all(np.abs(pre + K @ iota) <= robot.dq_max * (1 + 1e-9))
        assert np.all(np.abs(terms.J.T @ iota) <= robot.tau_max * DURATION * (1 + 1e-9))
        edge_only = rng.dirichlet(np.ones(k)) @ np.array(impulses[1:])
        normal_part = NORMAL @ edge_only
        # inside the circumscribing pyramid (radius mu / cos(pi / k) at its vertices)
        assert np.linalg.norm(frame_tangents @ edge_only) <= mu / math.cos(math.pi / k) * abs(normal_part) * (1 + 1e-9)
    assert held > 0


@settings(max_examples=15)
@given(SEEDS, st.sampled_from(["crb", "gm"]), st.floats(0.02, 0.5), st.floats(1.2, 3.0), st.integers(3, 8))
def test_the_feasible_accelerations_shrink_as_the_friction_grows(robot, seed, model, mu, growth, k):
    """F(mu2) within F(mu1) for mu1 < mu2 (the edge impulse of (n + mu t) moves on a straight
    segment from the frictionless one as mu grows): for random objectives, the LP optimum over
    F(mu2) is at most that over F(mu1), and F(mu2)'s optimum lies in F(mu1); mu = 0 is the
    frictionless set. States where the guard binds at mu2 are left out (the segment bends)."""
    rng = np.random.default_rng(seed)
    terms, c = random_state(robot, rng, speed=0.3), wide_cycle(robot)
    mu2 = mu * growth
    W = response(terms, model)[1]
    if np.min(pyramid_directions(NORMAL, mu2, k) @ W @ NORMAL) <= EDGE_GUARD * (NORMAL @ W @ NORMAL):
        return
    box = list(zip(-robot.ddq_max * 5, robot.ddq_max * 5))

    def stacked(friction):
        expected = impact(terms, model, friction, 0.2, k)
        limits = [PostImpactVelocityLimit(expected, robot.dq_max), ImpulsiveTorqueLimit(expected, robot.tau_max, robot.dq_max)]
        parts = [raw_rows(limit, terms, c) for limit in limits]
        C = np.vstack([p[0] for p in parts])
        return C, np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts])

    sets = [stacked(f) for f in (0.0, mu, mu2)]
    for objective in rng.normal(size=(4, JOINTS)):
        values = []
        for C, lower, upper in sets:
            answer = linprog(-objective, A_ub=np.vstack([C, -C]), b_ub=np.concatenate([upper, -lower]), bounds=box)
            values.append(-answer.fun if answer.status == 0 else -math.inf)
            if answer.status == 0 and len(values) == 3:
                for C_looser, lower_looser, upper_looser in sets[:2]:
                    assert np.all(C_looser @ answer.x <= upper_looser + 1e-7) and np.all(C_looser @ answer.x >= lower_looser - 1e-7)
        assert values[2] <= values[1] + 1e-7 and values[1] <= values[0] + 1e-7


@pytest.mark.parametrize("model", ["crb", "gm"])
def test_the_preview_rows_are_the_sector_opposing_a_certain_slip_and_the_whole_cone_otherwise(robot, model):
    """A fast slide barely approaching the wall: certain, the rows are those of the sector's edges
    n - mu / cos(alpha / 2) (cos(theta) s + sin(theta) n x s), theta = -alpha, 0, alpha; at rest,
    and approaching fast, uncertain: the 3-edge pyramid's (mu_3 = 2 mu)."""
    rng = np.random.default_rng(3)
    terms, c = random_state(robot, rng, speed=0.3), wide_cycle(robot)
    tangent = np.array([0.0, 0.6, 0.8])
    sliding = np.linalg.pinv(terms.J) @ (0.5 * tangent - 0.001 * NORMAL)
    K, W = response(terms, model)
    dq_pre = rng.uniform(-1.0, 1.0, JOINTS)
    sector = [NORMAL - 0.4 / math.cos(SLIP_SECTOR / 2) * (math.cos(a) * tangent + math.sin(a) * np.cross(NORMAL, tangent))
              for a in (-SLIP_SECTOR, 0.0, SLIP_SECTOR)]
    for dq, directions in [(sliding, sector), (np.zeros(JOINTS), pyramid_directions(NORMAL, 0.4, 3)),
                           (np.linalg.pinv(terms.J) @ (0.05 * tangent - 0.5 * NORMAL), pyramid_directions(NORMAL, 0.4, 3))]:
        state = robot.terms(terms.q, dq)
        C = raw_rows(PostImpactVelocityLimit(impact(state, model, 0.4, mode="slip"), robot.dq_max), state, c)[0]
        assert C.shape[0] == 4 * JOINTS
        for i, d in enumerate(directions):
            iota = edge_impulse(W, d, terms.J @ dq_pre, 0.3)
            np.testing.assert_allclose(C[(i + 1) * JOINTS:(i + 2) * JOINTS] @ dq_pre, dq_pre + K @ iota, rtol=1e-8, atol=1e-8)


@settings(max_examples=200, deadline=None)
@given(SEEDS, st.floats(0.02, 1.0), st.floats(0.0, 1.0), st.sampled_from(["energetic", "kinematic"]))
def test_a_certain_slip_keeps_its_impulse_in_the_sector_its_rows_cover(seed, mu, c_r, law):
    """Random W, normals and contact velocities: where the preview calls the slip certain, the
    frictional impact (either law, e = c_r) slides throughout, and its impulse is a combination
    of n and the sector's three edges with non-negative weights (the cone the rows cover: the
    impulse of every vertex of that cone keeps the limits when the rows hold, as the rows are
    linear in the impulse)."""
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(3, 3))
    W = L @ L.T + 0.1 * np.eye(3)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    tangent = np.cross(normal, rng.normal(size=3))
    velocity = rng.uniform(0.01, 1.0) * tangent / np.linalg.norm(tangent) - rng.uniform(0.0, 0.3) * normal
    uncertain = pyramid_directions(normal, mu, 3)
    preview = uncertain.copy()
    slip_edges_into(velocity, W, normal, mu, c_r, preview)
    assume(not np.array_equal(preview, uncertain))
    impact_3d = frictional_impulse(W, normal, velocity, mu, c_r, law)
    assert impact_3d.mode == "slip"
    # the impulse lies in the cone of n and the three edges when non-negative weights give it (an LP)
    answer = linprog(np.zeros(4), A_eq=np.vstack([normal, preview]).T, b_eq=impact_3d.impulse, bounds=[(0.0, None)] * 4,
                     method="highs")
    assert answer.status == 0


@pytest.mark.parametrize(
    "arguments, fragment",
    [
        ((2.5,), "the friction of the impact rows"),
        ((-0.1,), "the friction of the impact rows"),
        ((0.3, 2), "the pyramid edges"),
        ((0.3, 17), "the pyramid edges"),
        ((0.3, 4.0), "the pyramid edges"),
        ((0.3, 4, "cone"), "the friction rows"),
    ],
)
def test_friction_rows_check_their_ranges(arguments, fragment):
    with pytest.raises(BadInputError, match=fragment):
        FrictionRows(*arguments)


def test_friction_rows_are_refused_with_classical_normal(robot):
    surface = Surface([0.5, 0.0, 0.5], NORMAL)
    with pytest.raises(BadInputError, match="classical_normal"):
        ExpectedImpact(surface, "classical_normal", friction=FrictionRows(0.2))


@settings(max_examples=10, deadline=None)
@given(standing_states(), st.sampled_from(HELD_CONTACT_METHODS), st.floats(0.05, 3.0), st.floats(0.05, 1.0),
       st.integers(3, 6), st.sampled_from(["pyramid", "slip"]))
def test_on_held_contacts_each_edge_is_the_predictors_jump_of_its_edge_impulse(state, model, speed, mu, k, mode):
    """The standing G1: each edge's G_i J v-, A_i v- and P_i v- are the impulse along d_i that
    ends compression (from the predictor's held-contact W), the predictor's own held-contact jump
    of that impulse (``JumpModel.predict`` with it: the feet still) and J^T of it; the
    post-impact-velocity rows stack the frictionless block (today's rows, bit for bit) and the
    edges' blocks."""
    _, q, v = state
    g1 = whole_body_robot()
    v = v + approach_velocity(q, speed)
    terms = g1.terms(q, v)
    rule = ActivationRule(always_active=True)
    impact = ExpectedImpact(wall_ahead(q), model, rule=rule, held_contacts=True, friction=FrictionRows(mu, k, mode))
    edges, impulses = impact.edge_matrices(terms), impact.edge_impulse_maps(terms)
    v_minus = terms.J @ v
    W = held_response_maps(jump_model(model), terms, NORMAL, 0.0)[1]
    directions = pyramid_directions(NORMAL, mu, k) if mode == "pyramid" else impact._edge_set.directions
    for i, iota in enumerate(vertex_impulses(W, v_minus, directions)):
        np.testing.assert_allclose(impulses[i] @ v_minus, iota, rtol=1e-12, atol=1e-12 * np.abs(iota).max())
        jump = jump_model(model).predict(terms, NORMAL, v_minus, impulse=iota).dq_jump
        np.testing.assert_allclose(edges.jump[i] @ v, jump, atol=1e-9 * np.abs(jump).max())
        np.testing.assert_allclose(edges.torque[i] @ v, terms.J.T @ iota, atol=1e-9 * np.abs(terms.J.T @ iota).max())
    cycle = ControlCycle(DT, np.full(g1.nv, -1e9), np.full(g1.nv, 1e9), 0.002)
    today = PostImpactVelocityLimit(ExpectedImpact(wall_ahead(q), model, rule=rule, held_contacts=True), g1.dq_max)
    stacked = PostImpactVelocityLimit(impact, g1.dq_max)
    expected, rows = today.compute(terms, cycle), stacked.compute(terms, cycle)
    assert stacked.rows == today.rows * (1 + impact.friction.count)
    assert np.array_equal(rows.C[:today.rows], expected.C) and np.array_equal(rows.upper[:today.rows], expected.upper)
