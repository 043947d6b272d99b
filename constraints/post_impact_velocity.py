"""Impact-aware joint velocity limits: the predicted post-impact velocity stays in the limits."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.robot import ModelTerms

from .constraint import Constraint, ControlCycle, symmetric_row_bounds
from .impact_model import ExpectedImpact


class PostImpactVelocityLimit(Constraint):
    """dq_min <= (I + A)(dq + ddq dt) <= dq_max (docs/qp-constraints.md), A the jump matrix.

    Criterion (b) of the maximum feasible speed. The rows are written at the jerk horizon h of
    the cycle (``ControlCycle``: h = 2 ms for the Panda at dt = 1 ms), in acceleration units:

        (I + A) ddq in [(-dq_max - (I + A) dq) / h, (dq_max - (I + A) dq) / h]

    so that they stay feasible from one cycle to the next under the jerk limits; since they
    held at the previous cycle (s = 0), they also hold at s = dt, the form above. Rows are
    unbounded while the expected impact's activation rule says no impact is coming, and relaxed
    to the largest correction the cycle allows when the state already violates them
    (``ControlCycle.recoverable``).
    """

    relaxed = True

    def __init__(self, impact: ExpectedImpact, dq_max: np.ndarray):
        self.impact = impact
        self.dq_max = np.asarray(dq_max, dtype=float)
        self.rows = len(self.dq_max)
        self.name = f"post_impact_velocity[{impact.name}]"

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        post_impact_velocity_rows(
            self.impact.matrices(terms).jump_matrix, terms.dq, self.dq_max, 1.0 / cycle.horizon,
            self.impact.is_active(terms), C, lower, upper,
        )


@njit(cache=True)
def post_impact_velocity_rows(jump_matrix, dq, dq_max, inv_h, active, C, lower, upper):
    """Kernel: C = I + A; bounds (+-dq_max - C dq) / h when active, unbounded otherwise."""
    n = dq.shape[0]
    for i in range(n):
        for j in range(n):
            C[i, j] = jump_matrix[i, j] + (1.0 if i == j else 0.0)
    symmetric_row_bounds(C, dq, dq_max, inv_h, active, lower, upper)
