"""Plain-numpy statements of the compiled kernels of the QP package (``controller.qp``): the
feasibility check, the active constraints, the interval test, the braking command and the
compiled cycle plan."""

import numpy as np

from impactqp.constraints import ControlCycle

from .constraints import reference_recoverable
from .constraints import reference_rows as reference_constraint_rows
from .tasks import reference_rows as reference_task_rows


def reference_violation(problem, x) -> float:
    """``QpProblem.violation``: the largest violation of [lb; l] <= [x; C x] <= [ub; u], inf for
    a non-finite x; the gaps are left in ``problem.lower_gap`` and ``problem.upper_gap``."""
    if not np.isfinite(x).all():
        return np.inf
    z = np.concatenate([x, problem.C @ x])
    below = np.subtract(z, problem.lower, out=problem.lower_gap).min()
    above = np.subtract(problem.upper, z, out=problem.upper_gap).min()
    return max(-below, -above, 0.0)


def _row_starts(layout) -> np.ndarray:
    return np.array([s.start for s in layout.row_slices], dtype=int)


def reference_active_constraints(layout, box_bounds, problem, tolerance, ddq) -> list[str]:
    """``ImpactAwareController._active_constraints``: the boxes with ddq within ``tolerance`` of
    one of their own bounds, then the general constraints with a row gap (of the last
    ``violation``) within ``tolerance``."""
    box_tight = (np.abs(box_bounds - ddq) <= tolerance).any(axis=1)
    active = [
        c.name for c, lower, upper in zip(layout.box_constraints, box_tight[0::2], box_tight[1::2]) if lower or upper
    ]
    if layout.row_constraints:
        n = ddq.shape[0]
        tight = np.minimum(problem.lower_gap[n:], problem.upper_gap[n:]) <= tolerance
        per_constraint = np.logical_or.reduceat(tight, _row_starts(layout))
        active += [c.name for c, hit in zip(layout.row_constraints, per_constraint) if hit]
    return active


def reference_interval_conflicts(layout, problem, box_lower, box_upper, flags) -> bool:
    """``fallback.interval_conflicts`` on a cycle's problem: the same flags and the same return
    value."""
    p = problem
    n_boxes = len(layout.box_constraints)
    flags[:n_boxes] = ((box_lower == p.lb) | (box_upper == p.ub)).any(axis=1)
    flags[n_boxes:] = False
    if (p.lb > p.ub).any():
        return False
    if layout.row_constraints:
        low, high = p.C * p.lb, p.C * p.ub
        unreachable = (p.u < np.minimum(low, high).sum(axis=1)) | (p.l > np.maximum(low, high).sum(axis=1))
        flags[n_boxes:] = np.logical_or.reduceat(unreachable, _row_starts(layout))
    return True


def reference_braking_command(q, dq, previous_ddq, dt, ddq_max, dddq_max, robot):
    """``fallback.braking_command``: ddq, dq_cmd, q_cmd."""
    cycle = ControlCycle.after(previous_ddq, dt, ddq_max, dddq_max)
    ddq = np.clip(-dq / dt, cycle.acceleration_lower, cycle.acceleration_upper)
    dq_cmd = np.clip(dq + ddq * dt, -robot.dq_max, robot.dq_max)
    q_cmd = np.clip(q + (0.5 * dt) * (dq + dq_cmd), robot.q_min, robot.q_max)
    return ddq, dq_cmd, q_cmd


def reference_planned_qp(tasks, layout, terms, cycle: ControlCycle) -> tuple:
    """``cycle_plan.planned_rows``: the QP of ``tasks`` and of the constraints of ``layout`` at
    ``terms`` in plain numpy, (H, g, lb, ub, C, l, u, consistent): H = A^T W A and g = -A^T W b
    over the stacked task rows; [lb, ub] the boxes intersected, then clipped into the cycle's
    reachable interval; the general rows, the relaxed ones relaxed to what [lb, ub] reaches."""
    n = terms.dq.shape[0]
    A, b = np.zeros((0, n)), np.zeros(0)
    weights = np.zeros(0)
    for task in tasks:
        A_task, b_task = np.empty((task.rows, n)), np.empty(task.rows)
        reference_task_rows(task, terms, A_task, b_task)
        A, b, weights = np.vstack([A, A_task]), np.concatenate([b, b_task]), np.concatenate([weights, task.weight])
    H, g = A.T @ (weights[:, None] * A), -A.T @ (weights * b)
    lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
    for constraint in layout.box_constraints:
        lower, upper = np.empty(n), np.empty(n)
        reference_constraint_rows(constraint, terms, cycle, None, lower, upper)
        lb, ub = np.maximum(lb, lower), np.minimum(ub, upper)
    reach_lower, reach_upper = cycle.acceleration_lower, cycle.acceleration_upper
    lb, ub = np.clip(lb, reach_lower, reach_upper), np.clip(ub, reach_lower, reach_upper)
    C, l, u = np.empty((layout.rows, n)), np.empty(layout.rows), np.empty(layout.rows)
    for constraint, rows in zip(layout.row_constraints, layout.row_slices):
        reference_constraint_rows(constraint, terms, cycle, C[rows], l[rows], u[rows])
    first = layout.first_relaxed_row
    reference_recoverable(ControlCycle(cycle.dt, lb, ub, cycle.horizon), C[first:], l[first:], u[first:])
    return H, g, lb, ub, C, l, u, bool(np.all(lb <= ub))


def reference_integrate_command(q, dq, ddq, dt, robot, jump_matrix):
    """``cycle_kernels.integrate_command``: dq_cmd, q_cmd, the jump A dq_cmd, dq_cmd + A dq_cmd and
    whether dq_cmd was clipped."""
    free = dq + ddq * dt
    dq_cmd = np.clip(free, -robot.dq_max, robot.dq_max)
    q_cmd = np.clip(q + (0.5 * dt) * (dq + dq_cmd), robot.q_min, robot.q_max)
    jump = jump_matrix @ dq_cmd
    return dq_cmd, q_cmd, jump, dq_cmd + jump, bool(np.any(dq_cmd != free))
