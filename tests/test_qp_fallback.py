"""The fallback: a safe braking command for unusable states and infeasible QPs, the conflicting
constraints it names, and its compiled kernels against their numpy statements."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from conftest import JOINTS
from qp_states import DT, NORMAL, approach_controller
from reference.qp import reference_braking_command, reference_interval_conflicts

from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.qp import Command
from impactqp.controller.qp.fallback import conflict_names, interval_conflicts


def assert_safe_fallback(robot, controller, command, status, previous_ddq=np.zeros(JOINTS)):
    assert isinstance(command, Command)
    assert command.status == status and command.is_fallback
    for value in (command.ddq, command.dq_cmd, command.q_cmd, command.predicted_jump):
        assert np.all(np.isfinite(value))
    assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-9)
    assert np.all(np.abs(command.ddq - previous_ddq) <= robot.dddq_max * DT + 1e-9)
    assert np.all(np.abs(command.dq_cmd) <= robot.dq_max)
    assert np.all(command.q_cmd >= robot.q_min) and np.all(command.q_cmd <= robot.q_max)


def test_nan_state_gives_the_fallback(robot):
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q)
    first = controller.step(q, np.zeros(JOINTS))
    command = controller.step(np.full(JOINTS, np.nan), np.zeros(JOINTS))
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state", first.ddq)
    assert controller.fallback_count == 1
    fresh = approach_controller(robot, q)
    assert_safe_fallback(robot, fresh, fresh.step(q, [np.nan] * JOINTS), "fallback_invalid_state")
    assert_safe_fallback(robot, fresh, fresh.step([1.0, 2.0], None), "fallback_invalid_state")
    assert fresh.fallback_count == 2


@pytest.mark.parametrize("kind", [complex, bool, str])
def test_a_state_of_complex_numbers_booleans_or_text_gives_the_fallback_without_a_warning(robot, kind, recwarn):
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q)
    first = controller.step(q, np.zeros(JOINTS))
    command = controller.step(q.astype(kind), np.zeros(JOINTS))
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state", first.ddq)
    assert "q must hold real numbers" in command.message
    assert not recwarn.list


def test_state_outside_the_limits_gives_the_fallback(robot):
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q)
    outside = q.copy()
    outside[3] = robot.q_max[3] + 0.05
    command = controller.step(outside, np.zeros(JOINTS))
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state")
    assert command.violated_constraints == ["joint_position_limit"]
    too_fast = np.zeros(JOINTS)
    too_fast[0] = 1.1 * robot.dq_max[0]
    command = controller.step(q, too_fast)
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state", controller.memory.ddq)
    assert command.violated_constraints == ["joint_velocity_limit"]
    assert command.dq_cmd[0] < too_fast[0]  # braking
    assert controller.fallback_count == 2


def test_infeasible_request_gives_the_fallback_and_names_the_conflict(robot):
    """Approaching at 0.6 m/s with the impact constraints on: no acceleration of one cycle can
    bring the impulsive torque within its limit."""
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q)
    dq = 0.6 * approach_direction(robot, robot.terms(q), NORMAL)
    command = controller.step(q, dq)
    assert_safe_fallback(robot, controller, command, "fallback_infeasible")
    assert "impulsive_torque[crb]" in command.violated_constraints
    assert len(command.violated_constraints) >= 2  # with a limit on ddq: acceleration or torque
    assert np.linalg.norm(command.dq_cmd) < np.linalg.norm(dq)
    assert controller.fallback_count == 1


def test_the_irreducible_conflict_is_computed_on_demand(robot):
    """``step`` names a bounded conflicting set; the irreducible one (deletion filter) is
    computed only when asked for, after the fact."""
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q)
    assert controller.conflicting_constraints() == []  # no infeasible cycle yet
    command = controller.step(q, 0.6 * approach_direction(robot, robot.terms(q), NORMAL))
    assert command.status == "fallback_infeasible"
    irreducible = controller.conflicting_constraints()
    assert "impulsive_torque[crb]" in irreducible and len(irreducible) >= 2
    assert set(irreducible) <= {c.name for c in controller.constraints}


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jump=st.sampled_from(["crb", "gm", "robust"]), speed=st.floats(0.3, 0.8))
def test_compiled_conflict_and_braking_equal_the_numpy_reference(robot, seed, jump, speed):
    """On an infeasible cycle (a fast approach with the impact constraints on), the compiled
    interval test names the same conflicting set as its numpy statement, and the compiled
    braking command equals its numpy statement from random states and previous accelerations."""
    rng = np.random.default_rng(seed)
    q = PANDA.postures["elbow_up"].q
    controller = approach_controller(robot, q, jump=jump)
    dq = speed * approach_direction(robot, robot.terms(q), NORMAL)
    command = controller.step(q, dq)
    layout = controller.layout
    if command.status == "fallback_infeasible":
        problem = controller.problem
        fast, reference = layout.empty_flags(), ~layout.empty_flags()
        args = (controller._box_bounds, problem.lb, problem.ub, problem.C, problem.l, problem.u, layout.row_ends)
        expected = reference_interval_conflicts(layout, problem, controller._box_lower, controller._box_upper, reference)
        assert interval_conflicts(*args, fast) == expected
        np.testing.assert_array_equal(fast, reference)
        assert command.violated_constraints == conflict_names(layout, reference, True)
    for _ in range(5):
        q = robot.q_min + (robot.q_max - robot.q_min) * rng.uniform(-0.1, 1.1, JOINTS)
        dq = rng.uniform(-1.2, 1.2, JOINTS) * robot.dq_max
        controller.memory.ddq = rng.uniform(-1.0, 1.0, JOINTS) * robot.ddq_max
        expected = reference_braking_command(q, dq, controller.memory.ddq, DT, robot.ddq_max, robot.dddq_max, robot)
        command = controller._fallback(q, dq, "fallback_infeasible", [], "")
        for fast, reference in zip((command.ddq, command.dq_cmd, command.q_cmd), expected):
            np.testing.assert_allclose(fast, reference, rtol=1e-12, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_interval_test_flags_exactly_the_rows_no_point_of_the_box_satisfies(seed):
    """The span of C_i x over the box is attained at its vertices: a row is flagged exactly when
    every one of the 2^JOINTS vertices gives C_i x above u_i or every one below l_i."""
    rng = np.random.default_rng(seed)
    lb = rng.uniform(-2.0, 0.0, JOINTS)
    ub = lb + rng.uniform(0.0, 2.0, JOINTS)
    C = rng.normal(size=(6, JOINTS))
    centre = rng.normal(0.0, 4.0, 6)
    l, u = centre - rng.uniform(0.0, 1.0, 6), centre + rng.uniform(0.0, 1.0, 6)
    vertices = np.array(np.meshgrid(*zip(lb, ub), indexing="ij")).reshape(JOINTS, -1)
    values = C @ vertices
    unreachable = (values > u[:, None]).all(axis=1) | (values < l[:, None]).all(axis=1)
    row_ends = np.array([2, 3, 6])  # three constraints of 2, 1 and 3 rows
    box_bounds = np.vstack([lb, ub, lb - 1.0, ub + 1.0])  # box 0 sets [lb, ub], box 1 does not
    flags = np.zeros(5, dtype=np.bool_)
    assert interval_conflicts(box_bounds, lb, ub, C, l, u, row_ends, flags)
    expected = [unreachable[0:2].any(), unreachable[2:3].any(), unreachable[3:6].any()]
    np.testing.assert_array_equal(flags, [True, False, *expected])
    assert not interval_conflicts(box_bounds, ub + 1.0, lb, C, l, u, row_ends, flags)
