"""The relaxed impact rows widened within the held contacts' rows (``controller.qp.elastic_relaxation``):
a G1 state that already violates its impact rows gives a feasible, OK cycle that keeps the feet."""

import numpy as np
import pytest

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.qp import Status
from impactqp.controller.qp.elastic_relaxation import ElasticRelaxation
from impactqp.controller.qp.problem import QpProblem
from impactqp.controller.qp.solvers import SOLVED, DaqpSolver

NORMAL = np.array([-1.0, 0.0, 0.0])
IMPACT_ROWS = ("post_impact_velocity", "capture_region", "foot_wrench")


@pytest.fixture(scope="module")
def g1():
    return RobotModel("g1")


def fast_approach(robot, stance, speed):
    """The stance's posture with the hand moving at ``speed`` along the feet-held least-norm
    approach direction towards a wall 2 cm ahead, and the controller of that wall."""
    q = stance_posture(robot, STANCES[stance])
    terms = robot.terms(q)
    wall = Surface(terms.contact_point - 0.02 * NORMAL, NORMAL)
    controller = build_controller(ControllerConfig.approach(wall, 0.3, robot="g1"), robot, q)
    return controller, q, speed * approach_direction(robot, terms, NORMAL)


@pytest.mark.parametrize("stance, speed", [("parallel", 1.5), ("wide", 1.0), ("wide", 3.0), ("close", 3.0)])
def test_a_state_past_the_impact_rows_gives_an_ok_cycle_that_keeps_the_feet(g1, stance, speed):
    """Before: the rows relaxed over the box alone conflicted with the feet's equalities and
    the cycle fell back (fallback_infeasible)."""
    controller, q, v = fast_approach(g1, stance, speed)
    controller.reset(q, v)
    terms = g1.terms(q, v)
    command = controller.step(q, v)
    assert command.status == Status.OK, command.message
    assert np.all(np.isfinite(command.ddq))
    held = terms.held_jacobian @ command.ddq + terms.held_drift
    np.testing.assert_allclose(held, 0.0, atol=1e-6)
    assert any(name.startswith(IMPACT_ROWS) for name in command.active_constraints)


def random_problem(rng, n, fixed, relaxed):
    """A QP whose fixed rows (equalities) and box admit points and whose relaxed rows do not."""
    rows = fixed + relaxed
    problem = QpProblem.empty(rows, n)
    problem.H[:] = np.eye(n)
    problem.lb[:], problem.ub[:] = -1.0, 1.0
    problem.C[:] = rng.normal(size=(rows, n))
    x0 = rng.uniform(-0.5, 0.5, n)
    problem.l[:fixed] = problem.u[:fixed] = problem.C[:fixed] @ x0
    reach = np.abs(problem.C[fixed:]).sum(axis=1)
    problem.l[fixed:], problem.u[fixed:] = -np.inf, -reach - 1.0  # beyond anything the box reaches
    problem.u[fixed + relaxed // 2:] = np.inf  # half the relaxed rows hold whatever the point
    problem.l[fixed + relaxed // 2:] = -np.inf
    return problem


@pytest.mark.parametrize("seed", range(5))
def test_the_widened_rows_admit_a_point_of_the_fixed_rows_and_keep_the_rows_that_held(seed):
    rng = np.random.default_rng(seed)
    n, fixed, relaxed = 8, 3, 6
    problem = random_problem(rng, n, fixed, relaxed)
    before_l, before_u = problem.l.copy(), problem.u.copy()
    elastic = ElasticRelaxation(fixed + relaxed, fixed, n)
    assert elastic.widen(problem)
    solved, point = DaqpSolver(fixed + relaxed, n).solve(problem)
    assert solved == SOLVED and problem.violation(point) <= 1e-6  # the controller's acceptance
    np.testing.assert_array_equal(problem.l[:fixed], before_l[:fixed])
    np.testing.assert_array_equal(problem.u[:fixed], before_u[:fixed])
    held = slice(fixed + relaxed // 2, None)
    np.testing.assert_array_equal(problem.u[held], before_u[held])
    assert np.all(problem.u[fixed:fixed + relaxed // 2] > before_u[fixed:fixed + relaxed // 2])


def test_fixed_rows_with_no_point_leave_the_problem_unchanged():
    problem = random_problem(np.random.default_rng(7), 4, 2, 2)
    problem.l[0] = problem.u[0] = np.abs(problem.C[0]).sum() + 1.0  # beyond the box
    before = problem.lower.copy(), problem.upper.copy()
    assert not ElasticRelaxation(4, 2, 4).widen(problem)
    np.testing.assert_array_equal(problem.lower, before[0])
    np.testing.assert_array_equal(problem.upper, before[1])
