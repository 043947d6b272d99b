"""QpProblem and ConstraintLayout: the stacked bounds, the feasibility check and where each
constraint's rows sit."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.qp import reference_violation

from conftest import JOINTS
from impactqp.constraints import (
    AccelerationLimit,
    ExpectedImpact,
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
)
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.qp.problem import ConstraintLayout, QpProblem


def random_problem(rng, rows=5):
    lb = rng.uniform(-2.0, 0.0, JOINTS)
    l = rng.uniform(-2.0, 0.0, rows)
    return QpProblem(
        np.eye(JOINTS), np.zeros(JOINTS), rng.normal(size=(rows, JOINTS)), l, l + rng.uniform(0.0, 2.0, rows),
        lb, lb + rng.uniform(0.0, 2.0, JOINTS),
    )


def test_the_bounds_are_views_of_the_stacked_vectors():
    problem = QpProblem.empty(3, JOINTS)
    problem.lb[:] = -1.0
    problem.l[:] = -2.0
    problem.ub[:] = 1.0
    problem.u[:] = 2.0
    np.testing.assert_array_equal(problem.lower, [-1.0] * JOINTS + [-2.0] * 3)
    np.testing.assert_array_equal(problem.upper, [1.0] * JOINTS + [2.0] * 3)
    copy = problem.copy()
    copy.lower[0] = -5.0
    assert problem.lb[0] == -1.0


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-3, 1.0, 10.0]))
def test_compiled_violation_equals_the_numpy_reference(seed, scale):
    """The compiled feasibility check gives the largest violation and the gaps of its numpy
    statement; a feasible point has violation 0 and a non-finite one inf."""
    rng = np.random.default_rng(seed)
    problem = random_problem(rng)
    x = rng.normal(0.0, scale, JOINTS)
    fast = problem.violation(x)
    gaps = problem.lower_gap.copy(), problem.upper_gap.copy()
    assert fast == pytest.approx(reference_violation(problem, x), rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(gaps[0], problem.lower_gap, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(gaps[1], problem.upper_gap, rtol=1e-12, atol=1e-12)
    z = np.concatenate([x, problem.C @ x])
    assert (fast == 0.0) == bool(np.all(z >= problem.lower) and np.all(z <= problem.upper))
    assert problem.violation(np.full(JOINTS, np.nan)) == np.inf


def test_layout_puts_boxes_apart_and_relaxed_rows_last(robot):
    impact = ExpectedImpact(PANDA.postures["elbow_up"].surface)
    constraints = [
        PostImpactVelocityLimit(impact, robot.dq_max), AccelerationLimit(), TorqueLimit(robot.tau_max),
        VelocityLimit(robot.dq_max), ImpulsiveTorqueLimit(impact, robot.tau_max, robot.dq_max),
        PositionLimit(robot.q_min, robot.q_max, robot.ddq_max),
    ]
    layout = ConstraintLayout.of(constraints)
    assert all(c.is_box for c in layout.box_constraints)
    assert not any(c.is_box for c in layout.row_constraints)
    assert set(layout.box_constraints) | set(layout.row_constraints) == set(constraints)
    relaxed = [c.relaxed for c in layout.row_constraints]
    assert relaxed == sorted(relaxed)  # relaxed last, in one block
    assert layout.row_constraints[0].name == "joint_torque_limit"
    starts = [s.start for s in layout.row_slices]
    assert starts[0] == 0 and all(a.stop == b.start for a, b in zip(layout.row_slices, layout.row_slices[1:]))
    assert [s.stop - s.start for s in layout.row_slices] == [c.rows for c in layout.row_constraints]
    np.testing.assert_array_equal(layout.row_ends, [s.stop for s in layout.row_slices])
    assert layout.rows == sum(c.rows for c in layout.row_constraints)
    assert layout.first_relaxed_row == layout.row_constraints[0].rows
    assert layout.flag_names == tuple(c.name for c in layout.box_constraints + layout.row_constraints)
    assert layout.empty_box_bounds(robot.nv).shape == (2 * len(layout.box_constraints), robot.nv)
    assert ConstraintLayout.of([AccelerationLimit()]).rows == 0
