"""Plain-numpy statements of the compiled kernels of the QP package (``controller.qp``): the
feasibility check, the active constraints, the interval test and the braking command."""

import numpy as np

from impactqp.constraints import ControlCycle


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
