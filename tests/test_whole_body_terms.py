"""The standing G1's model terms (controller/model/whole_body_terms.py): drifts, M^-1 and
inputs."""

import numpy as np
import pytest
from hypothesis import given, settings
from whole_body_states import integrate, robot, standing_states, upright

from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=10, deadline=None)
EPS = 1e-6


@SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_drifts_are_the_time_derivatives_of_the_jacobians_along_the_motion(state):
    """d/dt (X v) = X dv + dX v: with dv = 0, (X(q + v eps) v - X(q) v) / eps -> dX v for the
    hand, the feet, the torso and the centre of mass (central differences)."""
    _, q, v = state
    model = robot()
    before, after, now = model.terms(integrate(q, v, -EPS), v), model.terms(integrate(q, v, EPS), v), model.terms(q, v)
    pairs = [
        (lambda t: t.J6 @ v, now.dJ6_dq),
        (lambda t: t.Jf @ v, now.dJf_dq),
        (lambda t: t.Jcom @ v, now.dJcom_dq),
        (lambda t: t.frame("torso").J6 @ v, now.frame("torso").dJ6_dq),
    ]
    for rate, drift in pairs:
        np.testing.assert_allclose((rate(after) - rate(before)) / (2 * EPS), drift, atol=1e-5 * (1 + np.abs(drift).max()))


@SETTINGS
@given(standing_states())
def test_inverse_inertia_and_centre_of_mass_match_their_definitions(state):
    _, q, v = state
    terms = robot().terms(q, v)
    np.testing.assert_allclose(terms.M @ terms.M_inv, np.eye(robot().nv), atol=1e-8)
    np.testing.assert_allclose(terms.M_inv, terms.M_inv.T, atol=1e-12)
    # the CoM velocity is the momentum over the mass: Jcom = (first three rows of the CMM) / m
    base = robot().base.terms(q)
    np.testing.assert_allclose(terms.Jcom, base.Jcom, atol=1e-12)
    np.testing.assert_allclose(terms.com, base.com, atol=1e-12)
    assert terms.mass == pytest.approx(base.mass)


def test_bad_states_are_refused():
    model = robot()
    q = model.terms(upright()).q
    nv = model.nv
    for bad_q, bad_v in ((q[:-1], np.zeros(nv)), (q, np.zeros(nv - 1)), (q, np.full(nv, np.nan))):
        with pytest.raises(BadInputError):
            model.terms(bad_q, bad_v)
