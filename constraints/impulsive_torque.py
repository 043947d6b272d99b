"""Impact-aware bound on the impulsive joint torque (the torque jump alone)."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.max_speed import DEFAULT_IMPACT_DURATION
from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle, symmetric_row_bounds
from .impact_model import ExpectedImpact
from impactqp.controller.model.validation import impact_duration as check_impact_duration


class ImpulsiveTorqueLimit(Constraint):
    """-tau_max <= J^T iota(dq + ddq dt) / delta_t <= tau_max, criterion (c) of docs/qp-constraints.md.

    iota = G J dq- is the impulse of the jump model ((12) for crb/gm, (5) for classical) and
    delta_t the impact duration, so the row is P (dq + ddq dt) / delta_t with P = J^T G J.
    In acceleration units, written at the jerk horizon h of the cycle like
    ``PostImpactVelocityLimit`` (recursive feasibility under the jerk limits; holds at dt too),
    with the row scale s_i = dq_max_i / (tau_max_i delta_t) that makes a torque at its limit
    read like a joint velocity at its limit:

        s_i P_i ddq in s_i [(-tau_max_i delta_t - P_i dq) / h, (tau_max_i delta_t - P_i dq) / h]

    Rows are unbounded while the expected impact's activation rule says no impact is coming, and
    relaxed to the largest correction the cycle allows when the state already violates them
    (``ControlCycle.recoverable``).

    With friction rows (``ExpectedImpact.friction``) the same rows of every edge's P_i follow,
    one block of joints rows per edge.
    """

    relaxed = True

    def __init__(
        self,
        impact: ExpectedImpact,
        tau_max: np.ndarray,
        dq_max: np.ndarray,
        impact_duration: float = DEFAULT_IMPACT_DURATION,
    ):
        impact_duration = check_impact_duration(impact_duration)
        self.impact = impact
        self.impulse_limit = np.asarray(tau_max, dtype=float) * impact_duration
        self._edges = impact.friction.count
        self.rows = len(self.impulse_limit) * (1 + self._edges)
        self.row_scale = np.asarray(dq_max, dtype=float) / self.impulse_limit
        self._scaling = np.vstack([self.row_scale, self.row_scale * self.impulse_limit])  # s_i; s_i tau_max_i delta_t
        self.name = f"impulsive_torque[{impact.name}]"

    def kernel_parameters(self) -> np.ndarray:
        """The row scales s, then s tau_max delta_t (one per row of the frictionless block each)."""
        return self._scaling.ravel()

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        if self._edges:
            self._stacked_rows_into(terms, cycle, C, lower, upper)
            return
        scaled_impulse_rows(
            self.impact.row_matrices(terms).torque_matrix, self._scaling, terms.dq, 1.0 / cycle.horizon,
            self.impact.is_active(terms), C, lower, upper,
        )

    def _stacked_rows_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        """The frictionless block, then one block per edge of the friction rows."""
        edge_scaled_impulse_rows(
            (self.impact.row_matrices(terms).torque_matrix, self.impact.edge_row_matrices(terms).torque), self._scaling,
            terms.dq, 1.0 / cycle.horizon, self.impact.is_active(terms), C, lower, upper,
        )


@njit(cache=True)
def scaled_impulse_rows(torque_matrix, scaling, dq, inv_h, active, C, lower, upper):
    """Kernel: C = diag(s) P; bounds (+-s tau_max delta_t - C dq) / h when active, unbounded
    otherwise (``scaling`` rows: s, then s tau_max delta_t)."""
    n = dq.shape[0]
    for i in range(n):
        for j in range(n):
            C[i, j] = torque_matrix[i, j] * scaling[0, i]
    symmetric_row_bounds(C, dq, scaling[1], inv_h, active, lower, upper)


@njit(cache=True)
def edge_scaled_impulse_rows(maps, scaling, dq, inv_h, active, C, lower, upper):
    """Kernel: the rows of ``scaled_impulse_rows`` for P, then for each edge's P_i, one block of
    joints rows each; ``maps`` = (P, the P_i stacked)."""
    torque_matrix, edge_torques = maps
    rows = dq.shape[0]
    scaled_impulse_rows(torque_matrix, scaling, dq, inv_h, active, C[:rows], lower[:rows], upper[:rows])
    for e in range(edge_torques.shape[0]):
        block = slice((e + 1) * rows, (e + 2) * rows)
        scaled_impulse_rows(edge_torques[e], scaling, dq, inv_h, active, C[block], lower[block], upper[block])
