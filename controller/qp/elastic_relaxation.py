"""The relaxed rows widened to a point the held contacts allow (a floating base's infeasible QP).

A cycle relaxes each row that the state already violates (``ControlCycle.recoverable``) to
the largest correction reachable over the cycle's box of accelerations, row by row. With held
contacts the reachable accelerations are the box *and* the contacts' equality rows
Jf ddq = -dJf dq: a row relaxed over the box alone may ask for an acceleration the feet forbid,
and the QP is infeasible while a correction that keeps the feet exists.

When that happens, this elastic problem finds the correction: in the unknowns (ddq, s), s one
slack per relaxed row,

    min  1/2 |s|^2 + 1/2 eps |ddq|^2
    s.t. lb <= ddq <= ub, s >= 0,                         (the cycle's box)
         l_F <= C_F ddq <= u_F,                           (every row that is not relaxed: the feet's)
         C_R ddq - s <= u_R,  C_R ddq + s >= l_R          (the relaxed rows, elastic)

its solution ddq_e meets every fixed row and violates the relaxed rows jointly as little as
possible (least squares). The relaxed rows are then widened to contain it, l_R <- min(l_R,
C_R ddq_e), u_R <- max(u_R, C_R ddq_e), so the cycle's QP is feasible (ddq_e is a point of it)
and rows that already held are unchanged; each widened bound leaves :data:`MARGIN` (relative) of
room around ddq_e, whose rows are tight at once: the solvers call such a degenerate point
infeasible. eps (:data:`REGULARIZATION`) only makes the problem
strictly convex: small against the slacks' weight 1.
"""

from __future__ import annotations

import numpy as np

from .problem import QpProblem
from .solvers import SOLVED, DaqpSolver, QuadprogSolver

REGULARIZATION = 1e-8  # eps: the weight of |ddq|^2 against the slacks' (module docstring)
MARGIN = 1e-7  # relative room the widened rows leave around ddq_e (a point on many rows at once is degenerate)


class ElasticRelaxation:
    """The elastic problem of the module docstring for a QP of ``variables`` unknowns whose rows
    from ``first_relaxed`` on are relaxed; allocated once, refilled at each use."""

    def __init__(self, rows: int, first_relaxed: int, variables: int):
        n, m = variables, rows - first_relaxed
        self.variables, self.first_relaxed, self.relaxed = n, first_relaxed, m
        self.problem = p = QpProblem.empty(first_relaxed + 2 * m, n + m)
        p.H[np.arange(n), np.arange(n)] = REGULARIZATION
        p.H[np.arange(n, n + m), np.arange(n, n + m)] = 1.0
        p.lb[n:], p.ub[n:] = 0.0, np.inf
        slack_rows = np.arange(first_relaxed, first_relaxed + m)
        p.C[slack_rows, np.arange(n, n + m)] = -1.0  # C_R ddq - s <= u_R
        p.C[slack_rows + m, np.arange(n, n + m)] = 1.0  # C_R ddq + s >= l_R
        p.l[first_relaxed:first_relaxed + m], p.u[first_relaxed + m:] = -np.inf, np.inf
        self.solver = DaqpSolver(p.C.shape[0], n + m)
        self.verifier = QuadprogSolver(p.C.shape[0], n + m)

    def widen(self, qp: QpProblem) -> bool:
        """Widen the relaxed rows of ``qp`` (in place) to contain the elastic problem's solution;
        False (``qp`` unchanged) when the fixed rows and the box admit no point."""
        n, first, m, p = self.variables, self.first_relaxed, self.relaxed, self.problem
        p.lb[:n], p.ub[:n] = qp.lb, qp.ub
        p.C[:first, :n], p.l[:first], p.u[:first] = qp.C[:first], qp.l[:first], qp.u[:first]
        relaxed = qp.C[first:]
        p.C[first:first + m, :n] = relaxed
        p.C[first + m:, :n] = relaxed
        p.u[first:first + m], p.l[first + m:] = qp.u[first:], qp.l[first:]
        solved, x = self.solver.solve(p)
        if solved != SOLVED:
            solved, x = self.verifier.solve(p)
        if solved != SOLVED or not np.all(np.isfinite(x)):
            return False
        reached = relaxed @ x[:n]
        margin = MARGIN * (1.0 + np.abs(reached))
        np.minimum(qp.l[first:], reached - margin, out=qp.l[first:])
        np.maximum(qp.u[first:], reached + margin, out=qp.u[first:])
        return True
