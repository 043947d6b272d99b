"""daqp on the G1's QP with the held contacts' rows eliminated (``controller.qp.held_elimination``):
the reduced QP is its numpy twin's, its solution is the full QP's to solver tolerance and keeps
the feet's rows; a singular chain falls back to the full QP; the controllers it serves."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.qp.held_elimination import HeldEliminationDaqp, held_chain_velocities, reduce_problem
from impactqp.controller.qp.solvers import SOLVED, DaqpSolver
from reference.held_elimination import reference_reduced_problem
from test_cycle_plan import setting_controller
from whole_body_states import controller, robot, stance, standing_states, wall_ahead


def filled(name, q, v, always):
    """The G1's default controller after one step at (q, v): its QP and its solver."""
    c = controller(name, gap=0.05, always_active=always)
    c.reset(q, v)
    c.step(q, v)
    return c


def held_slice(solver: HeldEliminationDaqp) -> slice:
    return slice(*solver.held)


@settings(max_examples=20, deadline=None)
@given(state=standing_states(), always=st.booleans())
def test_the_reduced_qp_is_its_twin_and_has_the_full_solution(state, always):
    name, q, v = state
    c = filled(name, q, v, always)
    solver, problem = c.solver, c.problem
    assert isinstance(solver, HeldEliminationDaqp)
    r = solver.reduced
    assert reduce_problem(
        (problem.H, problem.g, problem.C, problem.lower, problem.upper), (solver.held, solver.eliminated, solver.free),
        solver.substitution, (r.H, r.g, r.C, r.lower, r.upper),
    )
    expected = reference_reduced_problem(problem, held_slice(solver), solver.eliminated, solver.free)
    m = len(solver.free)
    actual = (r.H, r.g, r.C, r.lower, r.upper, solver.substitution[:, :m], solver.substitution[:, m])
    for a, b in zip(actual, expected):
        assert np.array_equal(np.isinf(a), np.isinf(b))
        finite = np.isfinite(b)
        assert np.allclose(a[finite], b[finite], rtol=1e-9, atol=1e-9)
    full_status, full_x = DaqpSolver(len(problem.l), robot().nv).solve(problem)
    status, x = solver.solve(problem)
    assert status == full_status
    if status == SOLVED:
        scale = max(1.0, np.abs(full_x).max())
        assert np.allclose(x, full_x, rtol=0.0, atol=1e-7 * scale)
        Jf = problem.C[held_slice(solver)]
        assert np.allclose(Jf @ x, problem.l[held_slice(solver)], rtol=0.0, atol=1e-9 * scale)


def test_a_singular_chain_falls_back_to_the_full_qp():
    """With a foot's chain block of Jf_e zeroed the substitution does not exist: the full QP's
    daqp answers."""
    c = filled("parallel", stance("parallel"), np.zeros(robot().nv), True)
    solver, problem = c.solver, c.problem.copy()
    problem.C[held_slice(solver).start:held_slice(solver).start + 6][:, solver.eliminated[:6]] = 0.0
    r = solver.reduced
    assert not reduce_problem(
        (problem.H, problem.g, problem.C, problem.lower, problem.upper), (solver.held, solver.eliminated, solver.free),
        solver.substitution, (r.H, r.g, r.C, r.lower, r.upper),
    )
    status, x = solver.solve(problem)
    expected_status, expected = DaqpSolver(len(problem.l), robot().nv).solve(problem)
    assert status == expected_status
    if status == SOLVED:
        assert np.allclose(x, expected, rtol=0.0, atol=1e-9)


def test_the_chains_and_the_controllers_it_serves():
    """The G1's eliminated velocities are its legs' (6 per foot, none of the base's); an arm's
    controller and a G1 on proxqp keep their solver."""
    model = robot()
    chains = held_chain_velocities(model)
    assert len(chains) == 12 and len(set(chains.tolist())) == 12 and chains.min() >= model.base_nv
    assert type(setting_controller(RobotModel("panda"), "crb").solver) is DaqpSolver
    q = stance("parallel")
    config = ControllerConfig.approach(wall_ahead(q), 0.3, robot="g1", solver="proxqp")
    assert build_controller(config, model, q).solver.name == "proxqp"
