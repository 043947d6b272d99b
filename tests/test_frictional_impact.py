"""The 3-D frictional impact (controller/model/frictional_impact.py): eq. (12) without friction,
an independent scipy integration of the same law, and the identities every impact keeps."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from impactqp.controller.model.frictional_impact import RESTITUTION_MODELS, frictional_impulse
from impactqp.controller.model.jump import normal_impulse_map
from impactqp.controller.model.validation import BadInputError

from reference.frictional_impact import reference_impact


def random_case(seed: int):
    """An inverse inertia W (symmetric positive definite, condition number below about 100), a
    unit normal and an approaching contact velocity with a random tangential part."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    W = A @ A.T + 0.2 * np.eye(3) * np.trace(A @ A.T) / 3
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    tangential = rng.normal(size=3)
    tangential -= (tangential @ n) * n
    v = -rng.uniform(0.05, 0.5) * n + rng.uniform(0.0, 1.0) * rng.uniform(0.0, 0.5) * tangential
    return W, n, v


@settings(max_examples=200)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.0), st.sampled_from(RESTITUTION_MODELS))
def test_without_friction_the_impulse_is_eq_12(seed, restitution, model):
    W, n, v = random_case(seed)
    impact = frictional_impulse(W, n, v, 0.0, restitution, model)
    np.testing.assert_allclose(impact.impulse, normal_impulse_map(W, n, restitution) @ v, rtol=1e-12, atol=1e-15)
    assert impact.mode == "frictionless"


@pytest.mark.parametrize("model", RESTITUTION_MODELS)
@settings(max_examples=500)
@given(st.integers(0, 2**32 - 1), st.floats(0.02, 1.5), st.floats(0.0, 1.0))
def test_the_law_agrees_with_a_generic_ode_solver(model, seed, mu, restitution):
    """The same equations integrated by scipy's DOP853 with its own event location, on 1,000
    random cases (500 per restitution model): impulse within 1e-6 (relative to its size), the
    same contact mode. Left out: mu within 0.1 % of the
    stick coefficient mu_bar, the boundary between stick and slip, where a slip slows towards
    rest at a rate proportional to mu - mu_bar and the answer hangs on the direction of a
    vanishing tangential velocity (a case at 0.006 % from it differed by 3e-5 between two
    correct integrations)."""
    W, n, v = random_case(seed)
    impact = frictional_impulse(W, n, v, mu, restitution, model)
    assume(abs(mu - impact.mu_bar) > 1e-3 * impact.mu_bar)
    impulse, post, mode = reference_impact(W, n, v, mu, restitution, model)
    size = np.linalg.norm(impulse)
    np.testing.assert_allclose(impact.impulse, impulse, rtol=0, atol=1e-6 * size)
    np.testing.assert_allclose(impact.post_velocity, post, rtol=0, atol=1e-6 * np.linalg.norm(v))
    assert impact.mode == mode


NEAR_THE_STICK_COEFFICIENT = (1 - 0.01, 1 - 0.003, 1 - 0.0011, 1 + 0.0011, 1 + 0.003, 1 + 0.01)


@pytest.mark.parametrize("model", RESTITUTION_MODELS)
@pytest.mark.parametrize("seed, restitution", [(3790057, 1.0), (19, 0.5), (53, 0.5), (354, 0.5)])
def test_the_law_agrees_with_the_ode_solver_next_to_the_stick_coefficient(seed, restitution, model):
    """Where slip slows towards rest (mu within 1 % of mu_bar, on both sides: slip or
    reversal below, stick above) the slip direction turns fast near u_t = 0 and a slow slip
    runs long: the law agrees with scipy's DOP853 to 1e-7 there too (impulse relative to its
    size, post-impact contact velocity relative to |v-|), in the same mode. The former
    fixed-step Runge-Kutta integration (2000 steps per frictionless impulse, steps near a stop
    changing u_t by 0.5 %) missed 7 of these 8 cases, by up to 1.6e-5."""
    W, n, v = random_case(seed)
    mu_bar = frictional_impulse(W, n, v, 0.0, restitution, model).mu_bar
    for factor in NEAR_THE_STICK_COEFFICIENT:
        impact = frictional_impulse(W, n, v, factor * mu_bar, restitution, model)
        impulse, post, mode = reference_impact(W, n, v, factor * mu_bar, restitution, model)
        np.testing.assert_allclose(impact.impulse, impulse, rtol=0, atol=1e-7 * np.linalg.norm(impulse))
        np.testing.assert_allclose(impact.post_velocity, post, rtol=0, atol=1e-7 * np.linalg.norm(v))
        assert impact.mode == mode


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.5), st.floats(0.0, 1.0), st.sampled_from(RESTITUTION_MODELS))
def test_the_least_tangential_speed_is_that_of_the_ode_solvers_path(seed, mu, restitution, model):
    """The smallest |u_t| along the impact: scipy's dense path's (refined by a scalar search)
    within 0.1 % (the law reads it at its steps' ends; a step changes u_t by a chord of at most
    5 % of |u_t|, which passes at most 1 - sqrt(1 - 0.025^2) = 0.03 % closer to 0), 0 to the
    stop threshold once the contact stopped (stick, reversal), at most the start's and the end's
    tangential speeds. Left out as above: mu within 0.1 % of mu_bar."""
    W, n, v = random_case(seed)
    impact = frictional_impulse(W, n, v, mu, restitution, model)
    assume(abs(mu - impact.mu_bar) > 1e-3 * impact.mu_bar)
    *_, least = reference_impact(W, n, v, mu, restitution, model, with_least_speed=True)
    speed = np.linalg.norm(v)
    assert impact.least_tangential_speed == pytest.approx(least, rel=1e-3, abs=1e-9 * speed)
    tangential = [np.linalg.norm(x - (x @ n) * n) for x in (v, impact.post_velocity)]
    assert impact.least_tangential_speed <= min(tangential) * (1 + 1e-12) + 1e-9 * speed
    if impact.mode in ("stick", "reversal"):
        assert impact.least_tangential_speed <= 1e-9 * speed


@settings(max_examples=300)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.5), st.floats(0.0, 1.0), st.sampled_from(RESTITUTION_MODELS))
def test_every_impact_keeps_momentum_coulomb_and_its_restitution(seed, mu, restitution, model):
    """du = W dP integrated: v+ = v- + W P; the impulse lies in the friction cone and pushes
    away from the surface; the contact separates (n^T v+ >= 0); the energetic law never adds
    kinetic energy (Delta T = P^T (v- + v+) / 2 <= 0); the stick coefficient is |W_tt^-1 W_tn|."""
    W, n, v = random_case(seed)
    impact = frictional_impulse(W, n, v, mu, restitution, model)
    P = impact.impulse
    np.testing.assert_allclose(impact.post_velocity, v + W @ P, rtol=1e-9, atol=1e-12)
    normal = P @ n
    assert normal > 0.0
    assert np.linalg.norm(P - normal * n) <= mu * normal * (1 + 1e-9) + 1e-15
    assert impact.post_velocity @ n >= -1e-9 * np.linalg.norm(v)
    if model == "energetic":
        assert P @ (v + impact.post_velocity) / 2 <= 1e-12 * (P @ P) ** 0.5 * np.linalg.norm(v)
    # the stick coefficient in a tangent basis of our own: any rotation about n gives the same
    Q, _ = np.linalg.qr(np.column_stack([n, np.random.default_rng(seed).normal(size=(3, 2))]))
    Wc = Q.T @ W @ Q  # n first, then two tangents
    assert impact.mu_bar == pytest.approx(np.linalg.norm(np.linalg.solve(Wc[1:, 1:], Wc[1:, 0])), rel=1e-9)


@settings(max_examples=100)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_a_contact_sticks_when_friction_exceeds_the_stick_coefficient(seed, restitution):
    """With no tangential velocity at the impact and mu >= mu_bar, the contact sticks: its
    tangential velocity stays 0; with mu below mu_bar it slides off along a new direction."""
    W, n, v = random_case(seed)
    v = (v @ n) * n
    mu_bar = frictional_impulse(W, n, v, 0.5, restitution).mu_bar
    stuck = frictional_impulse(W, n, v, 1.01 * mu_bar + 1e-9, restitution)
    post = stuck.post_velocity
    assert stuck.mode == "stick" and np.linalg.norm(post - (post @ n) * n) <= 1e-9 * np.linalg.norm(v)
    if mu_bar > 1e-6:
        sliding = frictional_impulse(W, n, v, 0.5 * mu_bar, restitution)
        assert sliding.mode == "reversal"
        assert np.linalg.norm(sliding.post_velocity - (sliding.post_velocity @ n) * n) > 0.0


@pytest.mark.parametrize(
    "args, message",
    [
        ((np.eye(3), [0, 0, 1], [0, 0, 0.1], 0.3), "does not approach the surface"),
        ((np.eye(3), [0, 0, 1], [0, 0, -0.1], -0.3), "friction coefficient"),
        ((np.eye(2), [0, 0, 1], [0, 0, -0.1], 0.3), "3 x 3"),
        ((np.eye(3), [0, 0, 0], [0, 0, -0.1], 0.3), "normal"),
    ],
)
def test_bad_input_is_named(args, message):
    with pytest.raises(BadInputError, match=message):
        frictional_impulse(*args)
