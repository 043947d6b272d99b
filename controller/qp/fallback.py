"""The safe command of an unusable cycle (a joint-wise brake) and the constraints that conflict
in an infeasible one.

Braking, within the acceleration and jerk limits (``ControlCycle``)::

    ddq = clip(-dq / dt, reachable accelerations of the cycle)
    dq_cmd = clip(dq + ddq dt, -dq_max, dq_max),  q_cmd = clip(q + (dq + dq_cmd) dt / 2, q_min, q_max)

For a non-finite state the previous command stands in for (q, dq) (or, before any command, the
finite entries of q with zero velocity, mid-range for non-finite entries).

Conflicting constraints. Over the intersected box lb <= ddq <= ub, row C_i ddq spans
[r_i, R_i] (r_i = sum_j min(C_ij lb_j, C_ij ub_j), R_i with max); a general constraint with a
row u_i < r_i or l_i > R_i cannot be met anywhere in the box. The bounded set named during the
cycle is those constraints plus the box constraints that set a bound of the box (every
constraint with rows when none conflicts on its own). The irreducible set (a deletion filter,
one daqp feasibility solve per constraint) is computed only on demand, after the cycle.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError, all_finite, real_array

from .command import DDQ_MAX, DQ_MAX, JERK_STEP, Q_MAX, Q_MIN, CommandMemory
from .problem import ConstraintLayout, QpProblem
from .solvers import SOLVED, DaqpSolver


def usable_state(q, dq, memory: CommandMemory, robot: PandaModel) -> tuple[np.ndarray, np.ndarray]:
    """(q, dq) if finite with the right shapes, else the previous command (module docstring)."""
    try:
        q = real_array(q, "q").reshape(robot.nq)
        dq = real_array(dq, "dq").reshape(robot.nv)
    except (BadInputError, ValueError):
        q, dq = np.full(robot.nq, np.nan), np.full(robot.nv, np.nan)
    if all_finite(q, dq):
        return q, dq
    if memory.q_cmd is not None:
        return memory.q_cmd, memory.dq_cmd
    mid_range = 0.5 * (robot.q_min + robot.q_max)
    return np.where(np.isfinite(q), q, mid_range), np.zeros(robot.nv)


def brake(q, dq, previous_ddq, dt, limits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The braking command (ddq, dq_cmd, q_cmd) from a usable state; ``limits`` are the
    ``command.command_limits``."""
    ddq, dq_cmd, q_cmd = np.empty(len(dq)), np.empty(len(dq)), np.empty(len(q))
    braking_command(q, dq, previous_ddq, dt, limits, ddq, dq_cmd, q_cmd)
    return ddq, dq_cmd, q_cmd


def bounded_conflict(layout: ConstraintLayout, problem: QpProblem, box_bounds: np.ndarray, flags: np.ndarray) -> list[str]:
    """The conflicting set of the interval test (module docstring), compiled
    (``interval_conflicts``); ``flags`` is a scratch array of ``layout.empty_flags()``."""
    p = problem
    consistent = interval_conflicts(box_bounds, p.lb, p.ub, p.C, p.l, p.u, layout.row_ends, flags)
    return conflict_names(layout, flags, consistent)


def conflict_names(layout: ConstraintLayout, flags: np.ndarray, box_consistent: bool) -> list[str]:
    """The names of ``interval_conflicts``' flags: the conflicting rows (every general
    constraint when none is flagged) then the boxes that set a bound; the boxes alone when
    the box itself is empty or there are no general rows."""
    n_boxes = len(layout.box_constraints)
    names = layout.flag_names
    boxes = [name for name, hit in zip(names[:n_boxes], flags[:n_boxes]) if hit]
    if not box_consistent or not layout.row_constraints:
        return boxes
    rows = [name for name, hit in zip(names[n_boxes:], flags[n_boxes:]) if hit]
    return (rows or list(names[n_boxes:])) + boxes


def irreducible_conflict(
    layout: ConstraintLayout, names: list[str], problem: QpProblem, box_lower: np.ndarray, box_upper: np.ndarray
) -> list[str]:
    """An irreducible infeasible subset of the constraints ``names`` (tried in that order) of a
    stored infeasible cycle: its problem and the bounds of each box constraint (deletion filter,
    one daqp feasibility solve per constraint)."""
    rows = {c.name: (None, lower, upper) for c, lower, upper in zip(layout.box_constraints, box_lower, box_upper)}
    for c, s in zip(layout.row_constraints, layout.row_slices):
        rows[c.name] = (problem.C[s], problem.l[s], problem.u[s])

    n = problem.H.shape[0]

    def feasible(subset: list[str]) -> bool:
        lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
        C, l, u = [np.zeros((0, n))], [np.zeros(0)], [np.zeros(0)]
        for name in subset:
            C_rows, lower, upper = rows[name]
            if C_rows is None:
                lb, ub = np.maximum(lb, lower), np.minimum(ub, upper)
            else:
                C.append(C_rows)
                l.append(lower)
                u.append(upper)
        if np.any(lb > ub):
            return False
        C = np.vstack(C)
        check = QpProblem(np.eye(n), np.zeros(n), C, np.concatenate(l), np.concatenate(u), lb, ub)
        return DaqpSolver(C.shape[0], n).solve(check)[0] == SOLVED

    kept = list(names)
    for name in list(kept):
        trial = [n for n in kept if n != name]
        if not feasible(trial):
            kept = trial
    return kept


@njit(cache=True)
def interval_conflicts(box_bounds, lb, ub, C, l, u, row_ends, flags):
    """Kernel of the interval test of an infeasible cycle: flags[k] for box k when one of its
    bounds (rows 2k, 2k+1 of box_bounds) sets the intersected box [lb, ub]; then, when that box
    is not empty, flags of the general constraints (rows ending at row_ends) when one of their
    rows has u_i < r_i or l_i > R_i, [r_i, R_i] the span of C_i x over the box. Returns whether
    the box is consistent (lb <= ub)."""
    boxes = box_bounds.shape[0] // 2
    n = lb.shape[0]
    for k in range(boxes):
        hit = False
        for j in range(n):
            if box_bounds[2 * k, j] == lb[j] or box_bounds[2 * k + 1, j] == ub[j]:
                hit = True
                break
        flags[k] = hit
    for c in range(row_ends.shape[0]):
        flags[boxes + c] = False
    for j in range(n):
        if lb[j] > ub[j]:
            return False
    start = 0
    for c in range(row_ends.shape[0]):
        hit = False
        for i in range(start, row_ends[c]):
            low = 0.0
            high = 0.0
            for j in range(n):
                a = C[i, j] * lb[j]
                b = C[i, j] * ub[j]
                low += min(a, b)
                high += max(a, b)
            if u[i] < low or l[i] > high:
                hit = True
                break
        flags[boxes + c] = hit
        start = row_ends[c]
    return True


@njit(cache=True)
def braking_command(q, dq, previous_ddq, dt, limits, ddq, dq_cmd, q_cmd):
    """Kernel of the fallback: ddq = -dq / dt clipped into the reachable interval
    [max(-ddq_max, ddq_prev - s), min(ddq_max, ddq_prev + s)] (s = dddq_max dt), dq_cmd = dq + ddq dt
    within +-dq_max and q_cmd = q + (dq + dq_cmd) dt / 2 within [q_min, q_max] (``limits``: the
    stacked ``command_limits``)."""
    for j in range(q.shape[0]):
        ddq_max, jerk_step, dq_max = limits[DDQ_MAX, j], limits[JERK_STEP, j], limits[DQ_MAX, j]
        lower = max(-ddq_max, previous_ddq[j] - jerk_step)
        upper = min(ddq_max, previous_ddq[j] + jerk_step)
        ddq[j] = min(max(-dq[j] / dt, lower), upper)
        dq_cmd[j] = min(max(dq[j] + ddq[j] * dt, -dq_max), dq_max)
        q_cmd[j] = min(max(q[j] + 0.5 * dt * (dq[j] + dq_cmd[j]), limits[Q_MIN, j]), limits[Q_MAX, j])
