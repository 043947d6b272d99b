"""The centre-of-mass task (tasks/com_task.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from whole_body_states import integrate, robot, standing_states, upright

from impactqp.controller.model.validation import BadInputError
from impactqp.tasks.com_task import CentreOfMassTask

SETTINGS = settings(max_examples=10, deadline=None)
EPS = 1e-6


@SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_jacobian_is_minus_the_derivative_of_the_error(state):
    """de/dt = -A v: central differences of e = c* - c(q) along v."""
    _, q, v = state
    task = CentreOfMassTask(target=[0.1, 0.0, 0.6])
    terms = robot().terms(q, v)
    A = task.compute(terms).A
    derivative = (task.error(robot().terms(integrate(q, v, EPS))) - task.error(robot().terms(integrate(q, v, -EPS)))) / (2 * EPS)
    np.testing.assert_allclose(derivative, -A @ v, atol=1e-7)


@SETTINGS
@given(standing_states(), st.floats(0.0, 400.0), st.floats(0.0, 50.0))
def test_rows_ask_for_the_pd_acceleration_of_the_centre_of_mass(state, kp, kd):
    """A dv = b  <=>  ddc = Jcom dv + dJcom v = kp (c* - c) - kd dc."""
    _, q, v = state
    terms = robot().terms(q, v)
    task = CentreOfMassTask(target=terms.com + [0.01, -0.02, 0.0], stiffness=kp, damping=kd)
    rows = task.compute(terms)
    dv = np.linalg.lstsq(rows.A, rows.b, rcond=None)[0]
    expected = kp * (task.target - terms.com) - kd * (terms.Jcom @ v)
    np.testing.assert_allclose(terms.Jcom @ dv + terms.dJcom_dq, expected, atol=1e-9 * (1 + np.abs(expected).max()))


def test_reset_captures_the_current_centre_of_mass_and_bad_gains_are_refused():
    terms = robot().terms(upright())
    task = CentreOfMassTask()
    task.reset(terms)
    np.testing.assert_array_equal(task.target, terms.com)
    for bad in ({"stiffness": -1.0}, {"weight": (1.0, 1.0)}, {"target": [0.0, np.nan, 0.0]}):
        with pytest.raises(BadInputError):
            CentreOfMassTask(**bad)


@SETTINGS
@given(standing_states(), st.floats(1.0, 2000.0))
def test_a_held_target_is_kept_by_resets_and_asks_the_critically_damped_pd(state, kp):
    """hold(c*, kp, w): the rows ask kp (c* - c) - 2 sqrt(kp) Jcom v - dJcom v; a reset keeps c*."""
    _, q, v = state
    terms = robot().terms(q, v)
    task = CentreOfMassTask()
    task.reset(terms)
    target = terms.com + np.array([0.05, -0.02, 0.0])
    task.hold(target, kp, [3.0, 3.0, 1.0])
    task.reset(terms)
    rows = task.compute(terms)
    expected = kp * (target - terms.com) - 2 * np.sqrt(kp) * terms.Jcom @ v - terms.dJcom_dq
    np.testing.assert_allclose(rows.b, expected, atol=1e-9)
    np.testing.assert_array_equal(task.weight, [3.0, 3.0, 1.0])


def test_a_held_target_must_be_finite():
    with pytest.raises(BadInputError):
        CentreOfMassTask().hold([np.nan, 0.0, 0.0], 100.0, [1.0, 1.0, 1.0])
