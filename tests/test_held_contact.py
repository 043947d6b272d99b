"""The held contacts' equality rows (constraints/held_contact.py): the G1's feet."""

import numpy as np
from hypothesis import given, settings
from whole_body_states import integrate, robot, standing_states

from impactqp.constraints import ControlCycle, HeldContactRows

EPS = 1e-6


@settings(max_examples=10, deadline=None)
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_any_acceleration_on_the_rows_keeps_the_feet_twists(state):
    """With dv on the rows (lower = upper, C = Jf), the feet's twist Jf v is constant to first
    order: (Jf(q + v eps)(v + dv eps) - Jf(q - v eps)(v - dv eps)) / (2 eps) -> 0."""
    _, q, v = state
    terms = robot().terms(q, v)
    nv = robot().nv
    rows = HeldContactRows(12).compute(terms, ControlCycle(0.001, np.zeros(nv), np.zeros(nv), 0.001))
    np.testing.assert_array_equal(rows.lower, rows.upper)
    np.testing.assert_array_equal(rows.C, terms.held_jacobian)  # one 6-row block per foot: Jf
    rng = np.random.default_rng(0)
    dv = np.linalg.lstsq(rows.C, rows.lower, rcond=None)[0] + (np.eye(nv) - np.linalg.pinv(rows.C) @ rows.C) @ rng.normal(size=nv)
    ahead = robot().terms(integrate(q, v, EPS)).held_jacobian @ (v + dv * EPS)
    behind = robot().terms(integrate(q, v, -EPS)).held_jacobian @ (v - dv * EPS)
    np.testing.assert_allclose((ahead - behind) / (2 * EPS), 0.0, atol=1e-5 * (1 + np.abs(dv).max()))

