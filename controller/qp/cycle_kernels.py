"""The compiled kernels of one control cycle (``controller.ImpactAwareController``), each with a
plain-numpy twin in the tests: the QP cost of the stacked task rows, the intersection of the box
constraints, the velocity-limit test, the integration of a fixed-base command with its impact
prediction, and a solution's check with its active set."""

from __future__ import annotations

import numpy as np
from numba import njit

from .command import DQ_MAX, Q_MAX, Q_MIN
from .problem import stacked_violation


@njit(cache=True)
def weighted_least_squares(A, b, w, columns, H, g):
    """Kernel: H = A^T diag(w) A and g = -A^T diag(w) b, the QP cost of the stacked task rows.

    Each row adds w_r a_r a_r^T over its non-zero columns only: the one column ``columns[r]``
    when it is >= 0 (a posture or damping row, whose one entry the plan knows:
    ``cycle_plan.single_entry_columns``), else the non-zero columns gathered from the row (a
    frame's row has the velocities of its chain). The sums run row by row as the dense
    product's, so H and g are the same to rounding."""
    rows, n = A.shape
    H[:, :] = 0.0
    g[:] = 0.0
    gathered = np.empty(n, dtype=np.int64)
    values = np.empty(n)
    for r in range(rows):
        weight = w[r]
        if weight == 0.0:
            continue
        if columns[r] >= 0:
            c = columns[r]
            wa = weight * A[r, c]
            g[c] -= wa * b[r]
            H[c, c] += wa * A[r, c]
            continue
        count = 0
        for i in range(n):
            if A[r, i] != 0.0:
                gathered[count] = i
                values[count] = A[r, i]
                count += 1
        target = b[r]
        for s in range(count):
            i, wa = gathered[s], weight * values[s]
            g[i] -= wa * target
            for t in range(s, count):
                H[i, gathered[t]] += wa * values[t]
    for i in range(n):
        for j in range(i):
            H[i, j] = H[j, i]


@njit(cache=True)
def intersect_boxes(box_lower, box_upper, reachable_lower, reachable_upper, lb, ub):
    """Kernel: lb = max_k box_lower[k] and ub = min_k box_upper[k], each clipped into the
    reachable interval [reachable_lower, reachable_upper]; False when lb > ub somewhere."""
    consistent = True
    for j in range(lb.shape[0]):
        low, high = -np.inf, np.inf
        for k in range(box_lower.shape[0]):
            low = max(low, box_lower[k, j])
            high = min(high, box_upper[k, j])
        lb[j] = min(max(low, reachable_lower[j]), reachable_upper[j])
        ub[j] = min(max(high, reachable_lower[j]), reachable_upper[j])
        if lb[j] > ub[j]:
            consistent = False
    return consistent


@njit(cache=True)
def first_outside(values, limit):
    """Kernel: the first index with |values_i| > limit_i, -1 when there is none."""
    for i in range(values.shape[0]):
        if abs(values[i]) > limit[i]:
            return i
    return -1


COMMAND_ROWS = 4
"""Rows of ``integrate_command``'s output: dq_cmd, q_cmd, the predicted jump and dq_cmd + the jump."""


@njit(cache=True)
def integrate_command(q, dq, ddq, dt, limits, jump_matrix, out):
    """Kernel of a fixed base's command: out[0] = dq_cmd = clip(dq + ddq dt, +-dq_max), out[1] =
    q_cmd = clip(q + (dq + dq_cmd) dt / 2, q_min, q_max) (``limits``: the stacked
    ``command_limits``), out[2] = the predicted jump A dq_cmd of the jump matrix A at the
    commanded velocity and out[3] = dq_cmd + A dq_cmd, the predicted post-impact velocity; True
    when dq_cmd had to be clipped."""
    clipped = False
    n = q.shape[0]
    for i in range(n):
        v = dq[i] + ddq[i] * dt
        dq_max = limits[DQ_MAX, i]
        if v > dq_max:
            v, clipped = dq_max, True
        elif v < -dq_max:
            v, clipped = -dq_max, True
        out[0, i] = v
        out[1, i] = min(max(q[i] + 0.5 * dt * (dq[i] + v), limits[Q_MIN, i]), limits[Q_MAX, i])
    predicted_jump_rows(jump_matrix, out)
    return clipped


@njit(cache=True, inline="always")
def predicted_jump_rows(jump_matrix, out):
    """Kernel: out[2] = A dq_cmd, the predicted jump of the jump matrix A at the commanded velocity
    out[0], and out[3] = dq_cmd + A dq_cmd, the predicted post-impact velocity (the last rows of
    a command's kernel, fixed or floating base)."""
    n = out.shape[1]
    for i in range(n):
        jump = 0.0
        for j in range(n):
            jump += jump_matrix[i, j] * out[0, j]
        out[2, i] = jump
        out[3, i] = out[0, i] + jump


@njit(cache=True)
def checked_solution(C, x, bounds, gaps, box_bounds, row_ends, tol, flags):
    """Kernel of a solution's check: ``stacked_violation`` of x in the QP of C and the stacked
    ``bounds`` (its largest violation, returned; the gaps in ``gaps``), then
    ``tight_constraints``' flags of x at ``tol``."""
    violation = stacked_violation(C, x, bounds, gaps)
    tight_constraints(x, box_bounds, gaps, row_ends, tol, flags)
    return violation


@njit(cache=True)
def tight_constraints(x, box_bounds, gaps, row_ends, tol, flags):
    """Kernel: flags[k] for box k (bounds in rows 2k, 2k+1 of box_bounds) when x is within tol
    of one of its bounds, then flags of the general constraints (rows ending at row_ends) when
    one of their rows has a gap <= tol (``gaps``: the rows lower_gap, upper_gap of
    ``stacked_violation``)."""
    lower_gap, upper_gap = gaps[0], gaps[1]
    boxes = box_bounds.shape[0] // 2
    n = x.shape[0]
    for k in range(boxes):
        hit = False
        for j in range(n):
            if abs(box_bounds[2 * k, j] - x[j]) <= tol or abs(box_bounds[2 * k + 1, j] - x[j]) <= tol:
                hit = True
                break
        flags[k] = hit
    start = 0
    for c in range(row_ends.shape[0]):
        hit = False
        for r in range(start, row_ends[c]):
            if min(lower_gap[n + r], upper_gap[n + r]) <= tol:
                hit = True
                break
        flags[boxes + c] = hit
        start = row_ends[c]

