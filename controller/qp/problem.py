"""The QP of one cycle in preallocated arrays (``QpProblem``) and where each constraint's rows
sit in it (``ConstraintLayout``).

The QP in the joint acceleration ddq (one unknown per velocity: the arm's joints, or the base and
joint accelerations of the standing humanoid, ``whole_body``)::

    minimize    1/2 ddq^T H ddq + g^T ddq
    subject to  lb <= ddq <= ub          (box constraints, intersected)
                l  <= C ddq <= u         (general constraints, stacked)

The bounds are stored stacked, [lb; l] and [ub; u], the layout daqp reads directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from impactqp.constraints import Constraint


class QpProblem:
    """Preallocated QP data: cost 1/2 x^T H x + g^T x, box lb <= x <= ub, rows l <= C x <= u.

    The bounds live in two stacked vectors ``lower`` = [lb; l] and ``upper`` = [ub; u] (lb, l,
    ub and u are views of them), the layout daqp reads directly, themselves the rows of one
    array ``bounds``; infinite entries are unbounded. Its arrays are C-contiguous float64 (daqp
    reads them in place, ``daqp_api``). ``gaps`` holds the rows ``lower_gap`` and
    ``upper_gap`` of the last ``violation``.
    """

    def __init__(self, H, g, C, l, u, lb, ub):
        H, g, C = (np.ascontiguousarray(a, dtype=float) for a in (H, g, C))  # what daqp reads in place
        self._hold(H, g, C, np.stack([np.concatenate([lb, l]), np.concatenate([ub, u])]).astype(float))

    @classmethod
    def over(cls, H, g, C, bounds) -> QpProblem:
        """The QP whose data are these arrays themselves, no copy (views of a caller's buffer:
        ``cycle_plan.CycleBuffers``), ``bounds`` = [[lb; l], [ub; u]]."""
        problem = cls.__new__(cls)
        problem._hold(H, g, C, bounds)
        return problem

    def _hold(self, H, g, C, bounds) -> None:
        rows, n = C.shape[0], H.shape[0]
        self.H, self.g, self.C, self.bounds = H, g, C, bounds
        self.lower, self.upper = bounds
        self.lb, self.l = self.lower[:n], self.lower[n:]
        self.ub, self.u = self.upper[:n], self.upper[n:]
        self.gaps = np.zeros((2, n + rows))
        self.lower_gap, self.upper_gap = self.gaps  # [x; C x] - lower and upper - [x; C x]

    @classmethod
    def empty(cls, rows: int, variables: int) -> QpProblem:
        """Zeros for ``rows`` general rows in ``variables`` unknowns."""
        n = variables
        return cls(np.zeros((n, n)), np.zeros(n), np.zeros((rows, n)), np.zeros(rows), np.zeros(rows),
                   np.zeros(n), np.zeros(n))

    def copy(self) -> QpProblem:
        return QpProblem(self.H.copy(), self.g.copy(), self.C.copy(), self.l, self.u, self.lb, self.ub)

    def violation(self, x: np.ndarray) -> float:
        """Largest violation of a bound or row by x (0 when x is feasible, inf when x is not
        finite); the gaps to the bounds stay in ``lower_gap`` and ``upper_gap``."""
        return stacked_violation(self.C, x, self.bounds, self.gaps)


@dataclass(frozen=True, eq=False)
class ConstraintLayout:
    """Where the constraints sit in the stacked QP.

    Box constraints (C = I) are intersected into lb <= ddq <= ub; box k's own bounds are kept in
    rows 2k (lower) and 2k + 1 (upper) of a ``box_bounds`` array. General constraints are stacked
    in ``row_constraints`` order, the relaxed ones last (in one block that
    ``ControlCycle.recoverable`` relaxes at once); constraint c owns the rows ``row_slices[c]``,
    which end at ``row_ends[c]``. ``flag_names`` names one flag per constraint, boxes first.
    """

    box_constraints: tuple[Constraint, ...]
    row_constraints: tuple[Constraint, ...]
    row_slices: tuple[slice, ...]
    row_ends: np.ndarray
    flag_names: tuple[str, ...]

    @classmethod
    def of(cls, constraints: list[Constraint]) -> ConstraintLayout:
        boxes = tuple(c for c in constraints if c.is_box)
        rows = tuple(sorted((c for c in constraints if not c.is_box), key=lambda c: c.relaxed))
        slices = consecutive_slices([c.rows for c in rows])
        return cls(
            boxes, rows, slices, np.array([s.stop for s in slices], dtype=np.int64),
            tuple(c.name for c in boxes + rows),
        )

    @property
    def rows(self) -> int:
        """Number of general rows (C has that many)."""
        return int(self.row_ends[-1]) if len(self.row_ends) else 0

    @property
    def first_relaxed_row(self) -> int:
        return sum(c.rows for c in self.row_constraints if not c.relaxed)

    def empty_box_bounds(self, variables: int) -> np.ndarray:
        """Zeros for the interleaved bounds of the box constraints (rows 2k and 2k + 1)."""
        return np.zeros((2 * len(self.box_constraints), variables))

    def empty_flags(self) -> np.ndarray:
        """One boolean per constraint, in ``flag_names`` order."""
        return np.zeros(len(self.flag_names), dtype=np.bool_)


def consecutive_slices(sizes: list[int]) -> tuple[slice, ...]:
    """Slices of consecutive blocks of the given sizes, from 0."""
    ends = np.cumsum(sizes, dtype=int)
    return tuple(slice(int(end - size), int(end)) for size, end in zip(sizes, ends))


@njit(cache=True)
def stacked_violation(C, x, bounds, gaps):
    """Kernel of ``QpProblem.violation``: with z = [x; C x] and ``bounds`` = [lower; upper], the
    rows of ``gaps`` lower_gap = z - lower and upper_gap = upper - z; the largest violation
    max(0, -min gaps), inf for a non-finite x."""
    lower, upper = bounds[0], bounds[1]
    lower_gap, upper_gap = gaps[0], gaps[1]
    n = x.shape[0]
    worst = 0.0
    for i in range(n + C.shape[0]):
        if i < n:
            z = x[i]
        else:
            z = 0.0
            for j in range(n):
                z += C[i - n, j] * x[j]
        if not np.isfinite(z):
            return np.inf
        lower_gap[i] = z - lower[i]
        upper_gap[i] = upper[i] - z
        worst = max(worst, -lower_gap[i], -upper_gap[i])
    return worst
