"""Impact-aware joint velocity limits: the predicted post-impact joint velocities stay in the limits."""

from __future__ import annotations

import numpy as np
from numba import njit

from .constraint import Constraint, ControlCycle, symmetric_row_bounds
from .impact_model import ExpectedImpact


class PostImpactVelocityLimit(Constraint):
    """-dq_max <= S (I + A)(dq + ddq dt) <= dq_max (docs/qp-constraints.md), A the jump matrix of
    the expected impact and S the selection of the actuated joints: the last ``len(dq_max)``
    velocities (all of them for a fixed-base arm, the joints after the base twist for a
    floating base, whose generalized velocity jumps as a whole: dv_jump = A v-).

    Criterion (b) of the maximum feasible speed. The rows are written at the jerk horizon h of
    the cycle (``ControlCycle``: h = 2 ms for the Panda at dt = 1 ms), in acceleration units:

        S (I + A) ddq in [(-dq_max - S (I + A) dq) / h, (dq_max - S (I + A) dq) / h]

    so that they stay feasible from one cycle to the next under the jerk limits; since they
    held at the previous cycle (s = 0), they also hold at s = dt, the form above. Rows are
    unbounded while the expected impact's activation rule says no impact is coming, and relaxed
    to the largest correction the cycle allows when the state already violates them
    (``ControlCycle.recoverable``).

    With friction rows (``ExpectedImpact.friction``, docs/frictional-impacts.md) the same rows
    of every edge's jump A_i follow, block after block: (1 + edges) x joints rows, so that the
    post-impact velocity of the frictionless impulse and of every edge impulse (hence of every
    convex combination of them) stays in the limits.
    """

    relaxed = True

    def __init__(self, impact: ExpectedImpact, dq_max: np.ndarray):
        self.impact = impact
        self.dq_max = np.asarray(dq_max, dtype=float)
        self._edges = impact.friction.count
        self.rows = len(self.dq_max) * (1 + self._edges)
        self.name = f"post_impact_velocity[{impact.name}]"

    def kernel_parameters(self) -> np.ndarray:
        """dq_max (one per row of the frictionless block)."""
        return self.dq_max.copy()

    def compute_into(self, terms, cycle: ControlCycle, C, lower, upper) -> None:
        if self._edges:
            self._stacked_rows_into(terms, cycle, C, lower, upper)
            return
        post_impact_velocity_rows(
            self.impact.row_matrices(terms).jump_matrix, terms.dq, self.dq_max, 1.0 / cycle.horizon,
            self.impact.is_active(terms), C, lower, upper,
        )

    def _stacked_rows_into(self, terms, cycle: ControlCycle, C, lower, upper) -> None:
        """The frictionless block, then one block per edge of the friction rows."""
        edge_post_impact_velocity_rows(
            (self.impact.row_matrices(terms).jump_matrix, self.impact.edge_row_matrices(terms).jump), terms.dq, self.dq_max,
            1.0 / cycle.horizon, self.impact.is_active(terms), C, lower, upper,
        )


@njit(cache=True)
def post_impact_velocity_rows(jump_matrix, dq, dq_max, inv_h, active, C, lower, upper):
    """Kernel: C = the last rows of I + A (one per limit); bounds (+-dq_max - C dq) / h when
    active, unbounded otherwise."""
    n = dq.shape[0]
    offset = n - C.shape[0]
    for i in range(C.shape[0]):
        for j in range(n):
            C[i, j] = jump_matrix[offset + i, j] + (1.0 if offset + i == j else 0.0)
    symmetric_row_bounds(C, dq, dq_max, inv_h, active, lower, upper)


@njit(cache=True)
def edge_post_impact_velocity_rows(maps, dq, dq_max, inv_h, active, C, lower, upper):
    """Kernel: the rows of ``post_impact_velocity_rows`` for A, then for each edge's A_i, one
    block of len(dq_max) rows each; ``maps`` = (A, the A_i stacked)."""
    jump_matrix, edge_jumps = maps
    rows = dq_max.shape[0]
    post_impact_velocity_rows(jump_matrix, dq, dq_max, inv_h, active, C[:rows], lower[:rows], upper[:rows])
    for e in range(edge_jumps.shape[0]):
        block = slice((e + 1) * rows, (e + 2) * rows)
        post_impact_velocity_rows(edge_jumps[e], dq, dq_max, inv_h, active, C[block], lower[block], upper[block])
