"""daqp's C API on a workspace of our own (controller/qp/daqp_api.py): the same optimum as daqp's
own one-shot solve, warm-started along a sequence, the solution where the caller asks, daqp's
exit flags read back, and clear refusals."""

import daqp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.qp.daqp_api import DaqpWorkspace, workspace_solve
from impactqp.controller.qp.problem import QpProblem


def random_problem(rng, problem: QpProblem) -> None:
    """A strictly convex QP feasible at a known point, written into ``problem``."""
    rows, n = problem.C.shape
    A, point = rng.normal(size=(n, n)), rng.normal(size=n)
    C = rng.normal(size=(rows, n))
    problem.H[:], problem.g[:], problem.C[:] = A.T @ A + np.eye(n), rng.normal(size=n), C
    problem.l[:], problem.u[:] = C @ point - rng.uniform(0.0, 1.0, rows), C @ point + rng.uniform(0.0, 1.0, rows)
    problem.lb[:], problem.ub[:] = point - rng.uniform(0.1, 1.0, n), point + rng.uniform(0.1, 1.0, n)


def fresh_solve(problem: QpProblem) -> tuple:
    rows, n = problem.C.shape
    return daqp.solve(problem.H, problem.g, problem.C, problem.upper, problem.lower, np.zeros(n + rows, np.int32))


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 30), st.integers(0, 30), st.integers(0, 2**31))
def test_each_solve_of_a_sequence_is_the_fresh_optimum(variables, rows, seed):
    """One workspace, set up once, its problem's arrays rewritten in place between solves: every
    solve (from the previous working set) gives daqp's one-shot optimum, unique, to 1e-9, and its
    exit flag; a solve into a caller's array leaves the same x there."""
    rng = np.random.default_rng(seed)
    problem = QpProblem.empty(rows, variables)
    random_problem(rng, problem)
    workspace = DaqpWorkspace(rows, variables)
    assert workspace.setup(problem) >= 0
    for step in range(6):
        if step:
            random_problem(rng, problem)
        x_fresh, _, flag_fresh, _ = fresh_solve(problem)
        if step % 2:
            flag, x = workspace.solve()
        else:
            x = np.full(variables, np.nan)
            flag = workspace_solve(workspace.words, x)
        assert flag == flag_fresh == 1
        np.testing.assert_allclose(x, x_fresh, rtol=0.0, atol=1e-9)


def test_an_empty_row_interval_is_infeasible_and_inconsistent_bounds_fail_the_update():
    """daqp's flag -1 (infeasible) for l > u on a row it must activate, read back through the
    result's word; a box with lb > ub makes the update itself fail (a negative flag); after either
    the workspace must be set up again (a cold start)."""
    rng = np.random.default_rng(3)
    problem = QpProblem.empty(4, 5)
    random_problem(rng, problem)
    workspace = DaqpWorkspace(4, 5)
    assert workspace.setup(problem) >= 0
    problem.l[0], problem.u[0] = 1.0, -1.0
    assert workspace.solve()[0] == fresh_solve(problem)[2] == -1
    with pytest.raises(RuntimeError, match="no problem is set up"):
        workspace.solve()
    random_problem(rng, problem)
    assert workspace.setup(problem) >= 0 and workspace.solve()[0] == 1
    problem.lb[2], problem.ub[2] = 1.0, -1.0
    assert workspace.solve()[0] < 0
    with pytest.raises(RuntimeError, match="no problem is set up"):
        workspace.solve()
    random_problem(rng, problem)
    assert workspace.setup(problem) >= 0 and workspace.solve()[0] == 1


def test_arrays_daqp_cannot_read_in_place_are_refused():
    workspace = DaqpWorkspace(2, 3)
    problem = QpProblem.empty(2, 3)
    problem.H = np.asfortranarray(np.eye(3) + 0.1)  # not row-major
    with pytest.raises(ValueError, match="C-contiguous float64"):
        workspace.setup(problem)
    with pytest.raises(ValueError, match="2 rows in 3 unknowns"):
        workspace.setup(QpProblem.empty(3, 3))
    with pytest.raises(RuntimeError, match="no problem is set up"):
        workspace.solve()


def test_a_problem_copies_the_arrays_it_is_given_into_row_major_float64():
    """``QpProblem`` holds C-contiguous float64 arrays whatever it is given, so daqp reads them."""
    H = np.asfortranarray(np.array([[2.0, 1.0], [1.0, 3.0]]))
    problem = QpProblem(H, np.array([1, 2]), np.ones((1, 2))[:, ::1], [0], [1], [-1, -1], [1, 1])
    workspace = DaqpWorkspace(1, 2)
    assert workspace.setup(problem) >= 0
    flag, x = workspace.solve()
    np.testing.assert_allclose(x, fresh_solve(problem)[0], atol=1e-12)
