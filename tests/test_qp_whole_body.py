"""The whole-body QP controller of the standing G1 (controller/qp/whole_body.py), assembled by
controller/qp/whole_body_setup.py."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from whole_body_states import NORMAL, approach_velocity, controller, robot, stance, standing_states

from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=12, deadline=None)
TOLERANCE = 1e-6


def impact_rows(c):
    return [x for x in c.layout.row_constraints if x.relaxed]


@SETTINGS
@given(standing_states(), st.sampled_from(METHODS), st.floats(0.0, 1.0), st.booleans())
def test_every_row_holds_and_the_feet_do_not_accelerate_at_the_solution(state, method, speed, always):
    name, q, v = state
    c = controller(name, method=method, speed=speed, always_active=always)
    c.reset(q, v)
    command = c.step(q, v)
    assert not command.is_fallback, command.message
    dv = command.ddq
    assert c.problem.violation(dv) <= TOLERANCE
    terms = robot().terms(q, v)
    np.testing.assert_allclose(terms.held_jacobian @ dv + terms.held_drift, 0.0, atol=TOLERANCE)
    # the joints' own limits, the impact rows as the constraints write them
    base = robot().base_nv
    joints = dv[base:]
    assert np.all(np.abs(joints) <= robot().ddq_max + TOLERANCE)
    assert np.all(np.abs(command.dq_cmd[base:]) <= robot().dq_max)
    for constraint in impact_rows(c):
        C, lower, upper = np.zeros((constraint.rows, robot().nv)), np.zeros(constraint.rows), np.zeros(constraint.rows)
        constraint.compute_into(terms, c._row_cycle, C, lower, upper)
        if np.all(lower <= 0.0) and np.all(upper >= 0.0):  # the state keeps them: they are not relaxed
            assert np.all(C @ dv <= upper + TOLERANCE) and np.all(C @ dv >= lower - TOLERANCE)
    np.testing.assert_allclose(command.dq_cmd, v + dv * c.dt)


@SETTINGS
@given(st.sampled_from(sorted(STANCES)), st.sampled_from(METHODS), st.floats(2.0, 3.0))
def test_impact_rows_bind_when_the_approach_speed_is_pushed_up(name, method, asked):
    """The hand moves at just below the highest speed s* the impact rows allow (bisection on
    the rows at v = s d, dv = 0, d the least-norm feet-held approach at 1 m/s) and the task asks
    for more: an impact row is active at the solution, and the commanded velocity keeps the
    predicted post-impact joint velocities within their limits. The balance tasks (CoM, torso)
    are off, so that the impact rows alone keep the post-impact CoM velocity capturable."""
    c = controller(name, method=method, speed=asked, always_active=True, com_weight=0.0, torso_weight=0.0)
    q = stance(name)
    unit = approach_velocity(q, 1.0)

    def holds(s):
        terms = robot().terms(q, s * unit)
        for x in impact_rows(c):
            C, lower, upper = np.zeros((x.rows, robot().nv)), np.zeros(x.rows), np.zeros(x.rows)
            x.compute_into(terms, c._cycle, C, lower, upper)
            if np.any(upper < 0.0) or np.any(lower > 0.0):
                return False
        return True

    low, high = 0.0, asked
    for _ in range(40):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if holds(middle) else (low, middle)
    assert 0.1 < low < 0.99 * asked
    v = 0.999 * low * unit
    c.reset(q, v)
    command = c.step(q, v)
    assert not command.is_fallback, command.message
    assert any(x.name in command.active_constraints for x in impact_rows(c)), command.active_constraints
    maps = jump_model(method).unit_matrices(robot().terms(q, command.dq_cmd), NORMAL, 0.0)
    post = command.dq_cmd + maps.jump_matrix @ command.dq_cmd
    assert np.all(np.abs(post[robot().base_nv:]) <= robot().dq_max + 1e-9)


def test_closed_loop_approach_keeps_the_feet_and_reaches_the_asked_speed():
    c = controller("parallel", gap=0.2, speed=0.2)
    q, v = stance("parallel"), np.zeros(robot().nv)
    c.reset(q, v)
    feet = robot().frame_placements(q)
    for _ in range(300):
        command = c.step(q, v)
        assert not command.is_fallback, command.message
        q, v = command.q_cmd, command.dq_cmd
    terms = robot().terms(q, v)
    assert -NORMAL @ terms.J @ v == pytest.approx(0.2, abs=0.02)
    for name, placement in robot().frame_placements(q).items():
        if name in feet and "ankle" in name:
            np.testing.assert_allclose(placement.translation, feet[name].translation, atol=1e-3)


def test_unusable_states_brake_the_joints_with_the_feet_held():
    c = controller("wide")
    q = stance("wide")
    v = approach_velocity(q, 0.5)
    with pytest.raises(BadInputError):
        c.step(q[:-1], v)  # no previous command to stand in
    c.reset(q, v)
    first = c.step(q, v)
    for bad_q, bad_v, status in (
        (q, np.full(robot().nv, np.nan), "fallback_invalid_state"),
        (q, np.r_[np.zeros(robot().base_nv), 1e3 * np.ones(robot().n_joints)], "fallback_invalid_state"),
    ):
        command = c.step(bad_q, bad_v)
        assert command.status == status and np.all(np.isfinite(command.q_cmd))
        terms = robot().terms(first.q_cmd if np.isnan(bad_v).any() else bad_q, first.dq_cmd if np.isnan(bad_v).any() else bad_v)
        np.testing.assert_allclose(terms.held_jacobian @ command.ddq + terms.held_drift, 0.0, atol=1e-6)
