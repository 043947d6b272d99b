"""Impact-aware joint velocity limits of the standing humanoid: the predicted post-impact joint
velocities of the whole floating-base system stay within the joint velocity limits."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.whole_body_terms import WholeBodyTerms

from .constraint import Constraint, ControlCycle, symmetric_row_bounds
from .floating_impact import FloatingExpectedImpact


class FloatingPostImpactVelocityLimit(Constraint):
    """-dq_max <= S (I + A)(v + dv h) <= dq_max, S selecting the actuated joints (the last
    ``len(dq_max)`` velocities).

    A = K G J is the floating-base jump matrix of the expected impact (dv_jump = A v-, crb
    (12), (20)-(21) by default; gm (12), (22)-(23) or classical (5)-(6)), so (I + A) v- is the
    post-impact generalized velocity. As ``PostImpactVelocityLimit`` for the arm, the rows are
    written at the jerk horizon h of the cycle, in acceleration units,

        S (I + A) dv in [(-dq_max - S (I + A) v) / h, (dq_max - S (I + A) v) / h],

    which keeps them feasible from one cycle to the next under the jerk limits and, holding at
    s = 0 and s = h, at the commanded velocity v + dv dt too. Unbounded while the activation
    rule says no impact is coming; relaxed to the largest correction the cycle allows when the
    state already violates them.
    """

    relaxed = True

    def __init__(self, impact: FloatingExpectedImpact, dq_max: np.ndarray):
        self.impact = impact
        self.dq_max = np.asarray(dq_max, dtype=float)
        self.rows = self.dq_max.shape[0]
        self.name = f"post_impact_velocity[{impact.name}]"

    def compute_into(self, terms: WholeBodyTerms, cycle: ControlCycle, C, lower, upper) -> None:
        joint_post_impact_rows(
            self.impact.matrices(terms).jump_matrix, terms.dq, self.dq_max, 1.0 / cycle.horizon,
            self.impact.is_active(terms), C, lower, upper,
        )


@njit(cache=True)
def joint_post_impact_rows(jump_matrix, dq, dq_max, inv_h, active, C, lower, upper):
    """Kernel: C = the last rows of I + A (one per limit); bounds (+-dq_max - C v) / h when
    active, unbounded otherwise."""
    n = dq.shape[0]
    offset = n - C.shape[0]
    for i in range(C.shape[0]):
        for j in range(n):
            C[i, j] = jump_matrix[offset + i, j] + (1.0 if offset + i == j else 0.0)
    symmetric_row_bounds(C, dq, dq_max, inv_h, active, lower, upper)
