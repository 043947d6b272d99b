"""Solver backends: the same QPs give the same answers, and the confirming solver agrees."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from qp_states import NORMAL, approach_controller, random_feasible_state

from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp import available_backends
from impactqp.controller.qp.solvers import DaqpSolver, QuadprogSolver, make_solver, verifier_for


@pytest.mark.parametrize("posture", sorted(POSTURES))
def test_solver_backends_agree(robot, posture):
    """Same QPs, same answers; three cycles, so that the warm-started proxqp must notice that
    the jerk box moved (its stale multipliers would otherwise pass the residual checks)."""
    q = POSTURES[posture].q
    terms = robot.terms(q)
    dq = 0.12 * approach_direction(terms, NORMAL)  # near the speed limit: the impact rows bind
    results = {}
    for solver in available_backends():
        controller = approach_controller(robot, q, solver=solver)
        controller.reset(q, dq)
        commands = [controller.step(q, dq) for _ in range(3)]
        assert all(c.status == "ok" for c in commands), solver
        results[solver] = np.array([c.ddq for c in commands])
    reference = results["daqp"]
    for solver, ddq in results.items():
        assert np.allclose(ddq, reference, atol=1e-5), solver


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_confirming_solver_agrees_with_daqp(robot, seed):
    """quadprog, the second opinion behind daqp, finds the same optimum on feasible QPs of the
    controller, and both call a QP with an empty row interval infeasible."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, ("crb",), 0.0)
    controller = approach_controller(robot, q, solver="daqp")
    controller.step(q, dq)
    problem = controller.problem
    rows = problem.C.shape[0]
    status_daqp, x_daqp = DaqpSolver(rows).solve(problem)
    status_quadprog, x_quadprog = QuadprogSolver(rows).solve(problem)
    assert status_daqp == status_quadprog
    if status_daqp == "solved":
        np.testing.assert_allclose(x_quadprog, x_daqp, atol=1e-6)
    infeasible = problem.copy()
    infeasible.l[0], infeasible.u[0] = 1.0, -1.0  # l > u: no ddq can satisfy row 0
    assert DaqpSolver(rows).solve(infeasible)[0] == "infeasible"
    assert QuadprogSolver(rows).solve(infeasible)[0] == "infeasible"


def test_every_backend_name_makes_its_solver_and_a_different_verifier():
    for name in available_backends():
        solver = make_solver(name, 4)
        assert solver.name == name
        assert verifier_for(solver.name, 4).name != name


def test_an_unknown_backend_is_bad_input():
    with pytest.raises(BadInputError, match="not available"):
        make_solver("no_such_solver", 4)
