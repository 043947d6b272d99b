"""The G1's compiled whole-body cycle (model terms refilled in place, jump maps in one kernel)
against the plain-numpy statement of the same maths (tests/reference/whole_body.py): the same
terms, maps and QP rows, and the same solution."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.whole_body import reference_jump_maps, reference_terms
from whole_body_states import NORMAL, approach_velocity, controller, robot, stance, standing_states

from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.jump import jump_model

SETTINGS = settings(max_examples=15, deadline=None)
TERM_FIELDS = (
    "q", "dq", "M", "h", "M_inv", "J", "J6", "dJ6_dq", "JJt_inv", "contact_point", "contact_rotation", "held_jacobian",
    "held_drift", "Jcom", "dJcom_dq", "com", "mass", "inertia_com",
)


def assert_close(actual, expected, name=""):
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-9 * (1.0 + np.abs(expected).max()), err_msg=name)


@SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_terms_refilled_in_place_are_the_reference_terms(state):
    _, q, v = state
    model = robot()
    buffer = model.terms(q)
    stamp = buffer.stamp
    for terms in (model.terms(q, v), model.update_terms(buffer, q, v)):
        expected = reference_terms(model, q, v)
        for name in TERM_FIELDS:
            assert_close(getattr(terms, name), getattr(expected, name), name)
        for actual, wanted in zip(terms.frame("torso"), expected.frame("torso")):
            assert_close(actual, wanted, "torso")
    assert buffer.stamp != stamp


@SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0), st.sampled_from(METHODS), st.floats(0.0, 1.0))
def test_kernel_maps_are_the_reference_maps(state, method, restitution):
    _, q, v = state
    terms = robot().terms(q, v)
    for actual, expected in zip(
        jump_model(method).unit_matrices(terms, NORMAL, restitution), reference_jump_maps(terms, method, NORMAL, restitution)
    ):
        assert_close(actual, expected)


@SETTINGS
@given(st.sampled_from(["parallel", "wide"]), st.sampled_from(METHODS), st.floats(0.05, 0.5), st.integers(1, 20))
def test_the_cycle_builds_the_reference_rows_and_solution(stance_name, method, speed, cycles):
    """Along a closed approach loop, the QP assembled by ``step`` equals the QP assembled from
    the reference terms (with the reference maps), and so does the solution."""
    c = controller(stance_name, gap=0.05, method=method, always_active=True)
    q = stance(stance_name)
    v = approach_velocity(q, speed)
    c.reset(q, v)
    for _ in range(cycles):
        command = c.step(q, v)
        q, v = command.q_cmd, command.dq_cmd
    memory_ddq = c.memory.ddq.copy()
    command = c.step(q, v)
    assert not command.is_fallback, command.message
    fast = [x.copy() for x in (c.problem.H, c.problem.g, c.problem.C, c.problem.l, c.problem.u, c.problem.lb, c.problem.ub)]
    expected = reference_terms(robot(), q, v)
    c.impact._maps = reference_jump_maps(expected, method, NORMAL, c.impact.restitution)
    c.impact._active = c.impact.is_active(robot().terms(q, v))
    c.impact._stamp = expected.stamp
    c._cycle.advance(memory_ddq, c.ddq_max, c._jerk_step)
    c._assemble(expected, c._cycle)
    slow = (c.problem.H, c.problem.g, c.problem.C, c.problem.l, c.problem.u, c.problem.lb, c.problem.ub)
    for actual, wanted in zip(fast, slow):
        finite = np.isfinite(wanted)
        assert np.array_equal(finite, np.isfinite(actual))
        assert_close(actual[finite], wanted[finite])
    _, dv, _ = c._solve()
    assert_close(command.ddq, dv)
