"""The end of a fixed base's cycle on daqp in one compiled call (``SolvedCommand``).

Once the cycle's QP is written, the controller would solve it (``DaqpSolver.solve``), check the
solution against every row (``_checked``) and integrate the command (``integrate_command``):
three compiled calls and the Python between them. ``solved_command`` does the three in one
call, in daqp's workspace (``daqp_api``), reading the QP where the controller keeps it (its
``CycleBuffers``). A compiled call pays for each array it is given (numba types every argument
at every call), so the kernel reads few: the workspace's words, the buffers, the active
constraints' flags, one array of the controller's settings (dt, the tolerances, the sizes, the
joint limits and where each constraint's rows end), the arm's state, the jump matrix and the
command it writes.

What the kernel cannot accept goes back to the controller's own path, as if daqp had answered
there: a solution that violates a row is handed over for the second solver to confirm, a
failure as daqp's status (the workspace then set up afresh at the next solve).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import arm_state_views

from .command import JERK_STEP
from .cycle_kernels import COMMAND_ROWS, checked_solution, integrate_command
from .cycle_plan import CycleBuffers, cycle_buffer_views
from .daqp_api import workspace_solve
from .solvers import FAILED, INFEASIBLE, SOLVED, DaqpSolver

ACCEPTED, CLIPPED, INACCURATE, DAQP_INFEASIBLE, DAQP_FAILED = range(5)
"""``solved_command``'s outcomes."""
DT, FLAG_TOLERANCE, FEASIBILITY_TOLERANCE, TASK_ROWS, ROWS, BOXES = range(6)
"""The head of ``solved_command``'s ``settings``; the joint limits (``command_limits``) follow, then
the ends of the constraints' rows."""
SETTINGS_HEAD = 6
LIMIT_ROWS = JERK_STEP + 1


class SolvedCommand:
    """daqp's solve, the check and the command of a fixed base's QP in one compiled call (module
    docstring): the QP in ``buffers`` (its ``problem``), the check's ``row_ends`` (the layout's)
    and active constraints' ``flags``, the joint ``limits`` (``command_limits``)."""

    def __init__(self, solver: DaqpSolver, buffers: CycleBuffers, row_ends: np.ndarray, flags: np.ndarray,
                 limits: np.ndarray):
        self.solver, self.buffers, self.flags = solver, buffers, flags
        sizes = (buffers.task_A.shape[0], buffers.problem.C.shape[0], buffers.box_bounds.shape[0] // 2)
        self.settings = np.concatenate([np.zeros(TASK_ROWS), sizes, limits.ravel(), row_ends]).astype(float)

    def run(self, terms, jump_matrix: np.ndarray, dt: float, tolerance: float) -> tuple[tuple | None, tuple | None]:
        """(accepted, answer) at the terms' state: accepted = (ddq, the command's four rows of
        ``integrate_command``, whether dq_cmd was clipped) when the solution holds every row to
        ``tolerance``; else answer = daqp's (status, x) for the controller's own path to go on from,
        or None when the workspace is not set up for this QP yet (the controller solves)."""
        workspace = self.solver.workspace_for(self.buffers.problem)
        if workspace is None:
            return None, None
        settings = self.settings
        settings[DT], settings[FLAG_TOLERANCE], settings[FEASIBILITY_TOLERANCE] = dt, 10.0 * tolerance, tolerance
        out = np.empty((COMMAND_ROWS + 1, jump_matrix.shape[0]))
        outcome = solved_command(workspace.words, self.buffers.data, self.flags, settings, terms.arm_state, jump_matrix, out)
        if outcome <= CLIPPED:
            return (out[COMMAND_ROWS], out[:COMMAND_ROWS], outcome == CLIPPED), None
        if outcome == INACCURATE:
            return None, (SOLVED, out[COMMAND_ROWS].copy())
        self.solver.forget()
        return None, (INFEASIBLE if outcome == DAQP_INFEASIBLE else FAILED, None)


@njit(cache=True)
def solved_command(words, data, flags, settings, state, jump_matrix, out):
    """Kernel of ``SolvedCommand.run``: daqp's solve in its workspace (``workspace_solve``, of its
    ``words``), the solution x written into out[4]; its check (``checked_solution`` in the QP of
    ``data``, ``cycle_buffer_views``; the flags at ``settings[FLAG_TOLERANCE]``) and, when it
    holds every row to ``settings[FEASIBILITY_TOLERANCE]``, the command of ``integrate_command``
    at the arm's ``state`` (``arm_state_views``) in out[:4]. The outcome: ACCEPTED, CLIPPED
    (accepted, dq_cmd clipped), INACCURATE (solved, a row violated), DAQP_INFEASIBLE or
    DAQP_FAILED."""
    n = out.shape[1]
    x = out[COMMAND_ROWS]
    flag = workspace_solve(words, x)
    if flag < 1:
        return DAQP_INFEASIBLE if flag == -1 else DAQP_FAILED
    rows, limits_end = int(settings[ROWS]), SETTINGS_HEAD + LIMIT_ROWS * n
    views = cycle_buffer_views(data, n, int(settings[TASK_ROWS]), rows, int(settings[BOXES]))
    C, bounds, box_bounds = views[6], views[7], views[8]
    row_ends = settings[limits_end:].astype(np.int64)
    gaps = np.empty((2, n + rows))
    violation = checked_solution(C, x, bounds, gaps, box_bounds, row_ends, settings[FLAG_TOLERANCE], flags)
    if not violation <= settings[FEASIBILITY_TOLERANCE]:
        return INACCURATE
    _, _, _, _, dq, _, q = arm_state_views(state, n)
    limits = settings[SETTINGS_HEAD:limits_end].reshape((LIMIT_ROWS, n))
    return CLIPPED if integrate_command(q, dq, x, settings[DT], limits, jump_matrix, out) else ACCEPTED
