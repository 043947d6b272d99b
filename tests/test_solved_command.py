"""The end of a fixed base's cycle in one compiled call (controller/qp/solved_command.py) against
the three steps it replaces: daqp's solve, the solution's check and the command's integration."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from qp_states import approach_controller, random_feasible_state

from impactqp.controller.qp.cycle_kernels import COMMAND_ROWS, integrate_command
from impactqp.controller.qp.solved_command import SolvedCommand
from impactqp.controller.qp.solvers import DaqpSolver


def controller_at(robot, seed):
    """A daqp approach controller after one cycle at a random feasible state (its workspace set
    up for its QP), its terms and its one-call end."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, ("crb",), 0.0)
    controller = approach_controller(robot, q, solver="daqp")
    controller.reset(q, dq)
    controller.step(q, dq)
    return controller, controller._terms, controller._solved_command


def jump_matrix_of(controller, terms):
    return controller.impact.row_matrices(terms).jump_matrix


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_one_call_gives_what_the_three_steps_give(robot, seed):
    """At the same QP: daqp's solution through a fresh solver (the same problem set up cold: the
    optimum is unique), ``_checked``'s active flags, and ``integrate_command``'s command, to
    1e-9 (the solution) and bit for bit from it (the command's rows)."""
    controller, terms, tail = controller_at(robot, seed)
    assert isinstance(tail, SolvedCommand)
    jump = jump_matrix_of(controller, terms)
    accepted, answer = tail.run(terms, jump, controller.dt, controller.feasibility_tolerance)
    assert answer is None and accepted is not None
    ddq, command, clipped = accepted
    flags = controller._active_flags.copy()
    status, x = DaqpSolver(*controller.problem.C.shape).solve(controller.problem)
    assert status == "solved"
    np.testing.assert_allclose(ddq, x, rtol=0.0, atol=1e-9)
    assert controller._checked(ddq) <= controller.feasibility_tolerance
    np.testing.assert_array_equal(flags, controller._active_flags)
    expected = np.empty((COMMAND_ROWS, robot.nv))
    assert clipped == integrate_command(terms.q, terms.dq, ddq, controller.dt, controller._limits, jump, expected)
    np.testing.assert_array_equal(command, expected)


def test_what_it_cannot_accept_goes_back_as_daqps_answer(robot):
    """A solution that misses a (negative) tolerance comes back as daqp's solved x for the second
    solver to judge; an empty row interval as daqp's infeasible status, the solver then set up
    afresh; before the workspace is set up for the QP, nothing (the controller solves)."""
    controller, terms, tail = controller_at(robot, 11)
    jump = jump_matrix_of(controller, terms)
    accepted, answer = tail.run(terms, jump, controller.dt, -1.0)
    assert accepted is None and answer[0] == "solved"
    np.testing.assert_allclose(answer[1], DaqpSolver(*controller.problem.C.shape).solve(controller.problem)[1], atol=1e-9)
    controller.problem.l[0], controller.problem.u[0] = 1e3, -1e3
    accepted, answer = tail.run(terms, jump, controller.dt, controller.feasibility_tolerance)
    assert accepted is None and answer == ("infeasible", None)
    assert controller.solver.workspace_for(controller.problem) is None
    assert tail.run(terms, jump, controller.dt, controller.feasibility_tolerance) == (None, None)


def test_the_controller_commands_what_its_own_path_would(robot):
    """Two controllers along the same closed loop, one ending its cycles in one call and one on
    its own path (the one-call end removed): the same commands, statuses and active constraints."""
    q = robot.description.postures[sorted(robot.description.postures)[0]].q
    one_call, own_path = (approach_controller(robot, q, speed=0.5, solver="daqp") for _ in range(2))
    own_path._solved_command = None
    states = [(q, np.zeros(robot.nv))] * 2
    for _ in range(200):
        commands = [c.step(*s) for c, s in zip((one_call, own_path), states)]
        assert commands[0].status == commands[1].status
        assert commands[0].active_constraints == commands[1].active_constraints
        np.testing.assert_allclose(commands[0].dq_cmd, commands[1].dq_cmd, rtol=0.0, atol=1e-9)
        states = [(c.q_cmd, c.dq_cmd) for c in commands]
