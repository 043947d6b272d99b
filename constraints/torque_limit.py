"""Joint torque limits of the inverse dynamics tau = M ddq + h."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle


class TorqueLimit(Constraint):
    """-tau_max <= M ddq + h <= tau_max.

    Row i is divided by M_ii, so it reads in acceleration units:
    (M_i / M_ii) ddq in [(-tau_max_i - h_i) / M_ii, (tau_max_i - h_i) / M_ii].
    """

    name = "joint_torque_limit"

    def __init__(self, tau_max: np.ndarray):
        self.tau_max = np.asarray(tau_max, dtype=float)
        self.rows = len(self.tau_max)

    def kernel_parameters(self) -> np.ndarray:
        """tau_max (one per row)."""
        return self.tau_max.copy()

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        normalised_torque_rows(terms.M, terms.h, self.tau_max, C, lower, upper)


@njit(cache=True)
def normalised_torque_rows(M, h, tau_max, C, lower, upper):
    """Kernel: row i of -tau_max <= M ddq + h <= tau_max divided by M_ii."""
    for i in range(M.shape[0]):
        inv = 1.0 / M[i, i]
        for j in range(M.shape[1]):
            C[i, j] = M[i, j] * inv
        lower[i] = (-tau_max[i] - h[i]) * inv
        upper[i] = (tau_max[i] - h[i]) * inv
