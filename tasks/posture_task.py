"""Posture task: joint-space PD towards a reference posture."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.robot import NQ, ModelTerms
from impactqp.controller.model.validation import finite_vector, task_gain

from .task import Task, critical_damping


class PostureTask(Task):
    """ddq = kp (q* - q) - kd dq as 7 rows I ddq = b, kd = 2 sqrt(kp) by default.

    A target left as None is the posture at ``reset``. Usually given a small weight, so it
    only shapes the redundant (null-space) motion of the arm.
    """

    name = "posture"
    rows = NQ

    def __init__(self, target=None, stiffness: float = 10.0, damping: float | None = None, weight: float = 1e-2):
        self.target = None if target is None else finite_vector(target, NQ, "posture target")
        self._target_configured = self.target is not None
        self.stiffness = task_gain(stiffness, "posture stiffness")
        self.damping = critical_damping(self.stiffness) if damping is None else task_gain(damping, "posture damping")
        self.weight = np.full(NQ, task_gain(weight, "posture weight"))

    def reset(self, terms: ModelTerms) -> None:
        if not self._target_configured:
            self.target = terms.q.copy()

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        joint_pd_rows(terms.q, terms.dq, self.target, self.stiffness, self.damping, A, b)


@njit(cache=True)
def joint_pd_rows(q, dq, target, stiffness, damping, A, b):
    """Kernel: A = I, b = kp (q* - q) - kd dq (with target = q and kp = 0: the damping rows)."""
    n = q.shape[0]
    for i in range(n):
        for j in range(n):
            A[i, j] = 1.0 if i == j else 0.0
        b[i] = stiffness * (target[i] - q[i]) - damping * dq[i]
