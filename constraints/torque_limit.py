"""Joint torque limits of the inverse dynamics tau = M ddq + h."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.robot import ModelTerms

from .constraint import Constraint, ConstraintRows, ControlCycle


class TorqueLimit(Constraint):
    """-tau_max <= M ddq + h <= tau_max.

    Row i is divided by M_ii, so it reads in acceleration units:
    (M_i / M_ii) ddq in [(-tau_max_i - h_i) / M_ii, (tau_max_i - h_i) / M_ii].
    """

    name = "joint_torque_limit"
    rows = 7

    def __init__(self, tau_max: np.ndarray):
        self.tau_max = np.asarray(tau_max, dtype=float)

    def compute(self, terms: ModelTerms, cycle: ControlCycle) -> ConstraintRows:
        inv_diag = 1.0 / np.diagonal(terms.M)
        return ConstraintRows(
            terms.M * inv_diag[:, None],
            (-self.tau_max - terms.h) * inv_diag,
            (self.tau_max - terms.h) * inv_diag,
        )
