"""The standing humanoid's expected impact (constraints/floating_impact.py)."""

import numpy as np
import pytest
from whole_body_states import NORMAL, approach_velocity, robot, stance, wall_ahead

from impactqp.constraints.floating_impact import FloatingExpectedImpact
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.validation import BadInputError


def test_rule_is_on_while_approaching_near_the_wall_and_off_when_leaving_or_far():
    q = stance("parallel")
    impact = FloatingExpectedImpact(wall_ahead(q, 0.05))
    far = FloatingExpectedImpact(wall_ahead(q, 0.5))
    approaching, leaving = approach_velocity(q, 0.3), approach_velocity(q, -0.3)
    assert impact.is_active(robot().terms(q, approaching))
    assert not impact.is_active(robot().terms(q, leaving))
    assert not far.is_active(robot().terms(q, approaching))
    assert FloatingExpectedImpact(wall_ahead(q, 0.5), always_active=True).is_active(robot().terms(q, leaving))


@pytest.mark.parametrize("method", ["crb", "gm", "classical"])
def test_maps_are_the_predictors_of_the_state_computed_once_per_state(method):
    q = stance("wide")
    impact = FloatingExpectedImpact(wall_ahead(q), method, restitution=0.3)
    terms = robot().terms(q, approach_velocity(q, 0.2))
    maps = impact.matrices(terms)
    assert impact.matrices(terms) is maps
    np.testing.assert_allclose(maps.jump_matrix, jump_model(method).unit_matrices(terms, NORMAL, 0.3).jump_matrix)
    assert impact.matrices(robot().terms(q)) is not maps


def test_only_the_floating_base_methods_are_accepted():
    with pytest.raises(BadInputError):
        FloatingExpectedImpact(wall_ahead(stance("parallel")), "robust")
