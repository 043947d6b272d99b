"""Solver backends: the same QPs give the same answers, and the confirming solver agrees."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from qp_states import NORMAL, approach_controller, random_feasible_state

from conftest import JOINTS, g1_model
from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp import available_backends
from impactqp.controller.qp.solvers import (
    PROXQP_INNER_ITERATIONS,
    PROXQP_OUTER_ITERATIONS,
    DaqpSolver,
    ProxqpDenseSolver,
    QuadprogSolver,
    make_solver,
    verifier_for,
)


@pytest.mark.parametrize("posture", sorted(PANDA.postures))
def test_solver_backends_agree(robot, posture):
    """Same QPs, same answers; three cycles, so that the warm-started proxqp must notice that
    the jerk box moved (its stale multipliers would otherwise pass the residual checks)."""
    q = PANDA.postures[posture].q
    terms = robot.terms(q)
    dq = 0.12 * approach_direction(robot, terms, NORMAL)  # near the speed limit: the impact rows bind
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
    rows, variables = problem.C.shape
    status_daqp, x_daqp = DaqpSolver(rows, variables).solve(problem)
    status_quadprog, x_quadprog = QuadprogSolver(rows, variables).solve(problem)
    assert status_daqp == status_quadprog
    if status_daqp == "solved":
        np.testing.assert_allclose(x_quadprog, x_daqp, atol=1e-6)
    infeasible = problem.copy()
    infeasible.l[0], infeasible.u[0] = 1.0, -1.0  # l > u: no ddq can satisfy row 0
    assert DaqpSolver(rows, variables).solve(infeasible)[0] == "infeasible"
    assert QuadprogSolver(rows, variables).solve(infeasible)[0] == "infeasible"


def test_every_backend_name_makes_its_solver_and_a_different_verifier():
    for name in available_backends():
        solver = make_solver(name, 4, JOINTS)
        assert solver.name == name
        assert verifier_for(solver.name, 4, JOINTS).name != name


def test_an_unknown_backend_is_bad_input():
    with pytest.raises(BadInputError, match="not available"):
        make_solver("no_such_solver", 4, JOINTS)


@settings(max_examples=30, deadline=None)
@given(st.integers(8, 40), st.integers(1, 8), st.integers(0, 2**31))
def test_backends_solve_problems_of_any_size_alike(variables, rows, seed):
    """Every backend and verifier on a random strictly convex QP in ``variables`` unknowns with
    ``rows`` general rows feasible at a known point, equality rows included."""
    from impactqp.controller.qp.problem import QpProblem

    rng = np.random.default_rng(seed)
    A = rng.normal(size=(variables, variables))
    point = rng.normal(size=variables)
    C = rng.normal(size=(rows, variables))
    slack = rng.uniform(0.0, 1.0, size=rows) * (rng.random(rows) < 0.7)  # some rows are equalities
    problem = QpProblem(A.T @ A + np.eye(variables), rng.normal(size=variables), C, C @ point - slack, C @ point + slack,
                        point - 1.0, point + 1.0)
    answers = []
    for name in ("daqp", "proxqp", "qpsolvers:quadprog"):
        for solver in (make_solver(name, rows, variables), verifier_for(name, rows, variables)):
            status, x = solver.solve(problem)
            assert status == "solved" and problem.violation(x) <= 1e-6
            answers.append(x)
    for x in answers[1:]:
        np.testing.assert_allclose(x, answers[0], atol=1e-4)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31))
def test_daqps_warm_started_workspace_solves_each_problem_like_a_fresh_solve(seed):
    """One DaqpSolver refilled in place along a sequence of QPs (its workspace updated and
    warm-started from the previous working set) gives, at every step, the optimum of a fresh
    ``daqp.solve`` of that QP (to 1e-9, the optimum being unique), calls an empty row interval
    infeasible, and solves the next QP after it."""
    import daqp

    from impactqp.controller.qp.problem import QpProblem

    rng = np.random.default_rng(seed)
    variables, rows = 7, 10
    problem = QpProblem.empty(rows, variables)
    solver = DaqpSolver(rows, variables)
    for step in range(12):
        A = rng.normal(size=(variables, variables))
        point = rng.normal(size=variables)
        C = rng.normal(size=(rows, variables))
        problem.H[:], problem.g[:], problem.C[:] = A.T @ A + np.eye(variables), rng.normal(size=variables), C
        problem.l[:], problem.u[:] = C @ point - rng.uniform(0.0, 1.0, rows), C @ point + rng.uniform(0.0, 1.0, rows)
        problem.lb[:], problem.ub[:] = point - 1.0, point + 1.0
        if step == 6:
            problem.l[0], problem.u[0] = 1.0, -1.0  # l > u: no ddq can satisfy row 0
            assert solver.solve(problem) == ("infeasible", None)
            continue
        status, x = solver.solve(problem)
        fresh = daqp.solve(problem.H, problem.g, problem.C, problem.upper, problem.lower, np.zeros(variables + rows, np.int32))
        assert status == "solved" and fresh[2] == 1
        np.testing.assert_allclose(x, fresh[0], atol=1e-9)


def g1_approach_problems(cycles: int = 600) -> list:
    """The G1's whole-body QPs (a copy of each cycle's, with its status) along the closed loop of
    its approach to a wall 10 cm ahead at 0.5 m/s (daqp driving), up to its first infeasible QP
    (the hand past the wall) or ``cycles``."""
    robot = g1_model()
    q = stance_posture(robot, robot.description.stances["parallel"])
    surface = Surface(robot.terms(q).contact_point - 0.10 * NORMAL, NORMAL)
    controller = build_controller(ControllerConfig.approach(surface, 0.5, robot="g1"), robot, q)
    v = np.zeros(robot.nv)
    controller.reset(q, v)
    problems = []
    for _ in range(cycles):
        command = controller.step(q, v)
        problems.append((command.status, controller.problem.copy()))
        if command.status == "fallback_infeasible":
            break
        q, v = command.q_cmd, command.dq_cmd
    return problems


def test_proxqp_and_daqp_agree_on_the_g1_whole_body_qp():
    """Warm-started proxqp, fed the G1's QPs of one approach cycle after cycle, finds daqp's
    optimum of each (35 unknowns, the feet's equality rows, the impact rows, accelerations boxed
    from 3 to 3143 rad/s^2); on the first infeasible one it gives up within its iteration budget
    (its outer iterations times its inner ones: 200 and 200 allowed 40,200, about 1 s, from a
    warm start that hides the infeasibility), and daqp calls that QP infeasible."""
    problems = g1_approach_problems()
    assert problems[-1][0] == "fallback_infeasible" and all(s == "ok" for s, _ in problems[:-1])
    rows, variables = problems[0][1].C.shape
    proxqp, daqp_solver = ProxqpDenseSolver(rows, variables), DaqpSolver(rows, variables)
    for status, problem in problems[:-1]:
        solved, x = proxqp.solve(problem)
        reference = daqp_solver.solve(problem)[1]
        assert solved == "solved" and problem.violation(x) <= 1e-6
        np.testing.assert_allclose(x, reference, atol=1e-4 * max(1.0, np.abs(reference).max()))
    infeasible = problems[-1][1]
    assert proxqp.solve(infeasible)[0] != "solved"
    assert proxqp.qp.results.info.iter <= PROXQP_OUTER_ITERATIONS * (PROXQP_INNER_ITERATIONS + 1)
    assert DaqpSolver(rows, variables).solve(infeasible)[0] == "infeasible"
