"""The floating-base predictors as linear maps (controller/model/floating_maps.py) against the
predictors themselves (controller/model/floating_base.py)."""

import numpy as np
import pytest
from conftest import unit_vectors
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.whole_body import feet_held_pinv
from whole_body_states import robot, standing_states, upright

from impactqp.controller.model.capture import com_jump_map
from impactqp.controller.model.floating_base import METHODS, predict
from impactqp.controller.model.floating_maps import floating_jump_maps
from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=15, deadline=None)


@SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0), st.sampled_from(METHODS), unit_vectors(), st.floats(0.0, 1.0))
def test_maps_give_the_predictors_jump_impulse_and_com_map(state, method, normal, restitution):
    """A v = dv and G J v = iota of ``predict`` at v- = J v; C = Jcom P J^T."""
    _, q, v = state
    terms, base = robot().terms(q, v), robot().base.terms(q)
    maps = floating_jump_maps(terms, method, normal, restitution)
    if abs(normal @ terms.J @ v) < 1e-3:
        v = v + feet_held_pinv(terms.J, terms.Jf) @ (-0.1 * normal)
    jump = predict(base, method, normal, terms.J @ v, restitution)
    scale = 1.0 + np.abs(jump.dv).max()
    np.testing.assert_allclose(maps.jump_matrix @ v, jump.dv, atol=1e-8 * scale)
    np.testing.assert_allclose(maps.impulse_map @ (terms.J @ v), jump.impulse, atol=1e-8 * (1 + np.abs(jump.impulse).max()))
    np.testing.assert_allclose(maps.com_map, com_jump_map(base), atol=1e-10)


@SETTINGS
@given(standing_states(max_joint_offset=0.3))
def test_feet_held_pinv_is_a_right_inverse_that_keeps_the_feet_still(state):
    _, q, _ = state
    terms = robot().terms(q)
    Jsharp = feet_held_pinv(terms.J, terms.Jf)
    np.testing.assert_allclose(terms.J @ Jsharp, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(terms.Jf @ Jsharp, 0.0, atol=1e-9)
    np.testing.assert_allclose(Jsharp, robot().base.terms(q).feet_held_pinv(), atol=1e-8)


def test_unknown_method_is_refused():
    terms = robot().terms(upright())
    with pytest.raises(BadInputError):
        floating_jump_maps(terms, "robust", np.array([-1.0, 0, 0]), 0.0)
