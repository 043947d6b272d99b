"""Posture task: joint-space PD towards a reference posture."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import BadInputError, finite_vector, task_gain

from .task import Task, critical_damping


class PostureTask(Task):
    """ddq = kp (q* - q) - kd dq as ``joints`` rows (one per actuated joint; the size of
    ``target`` when ``joints`` is left out), kd = 2 sqrt(kp) by default.

    The actuated joints are the last ``joints`` entries of q and of the velocity (a floating
    base's coordinates come first), so the rows are [0 I] ddv = b: on the arm, I ddq = b. A
    target left as None is the posture at ``reset``. Usually given a small weight, so it only
    shapes the redundant (null-space) motion.
    """

    name = "posture"

    def __init__(
        self, target=None, stiffness: float = 10.0, damping: float | None = None, weight: float = 1e-2,
        joints: int | None = None,
    ):
        if joints is None and target is None:
            raise BadInputError("a posture task needs its target or its number of joints")
        self.rows = len(finite_vector(target, None, "posture target")) if joints is None else int(joints)
        self.target = None if target is None else finite_vector(target, self.rows, "posture target")
        self._target_configured = self.target is not None
        self.stiffness = task_gain(stiffness, "posture stiffness")
        self.damping = critical_damping(self.stiffness) if damping is None else task_gain(damping, "posture damping")
        self.weight = np.full(self.rows, task_gain(weight, "posture weight"))

    def reset(self, terms: ModelTerms) -> None:
        if not self._target_configured:
            self.target = terms.q[-self.rows:].copy()

    def kernel_parameters(self) -> np.ndarray:
        """kp, kd, the target (rows) and the weights (rows)."""
        return np.concatenate([[self.stiffness, self.damping], self.target, self.weight])

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        n = self.rows
        if A.shape[1] == n:
            joint_pd_rows(terms.q, terms.dq, self.target, self.stiffness, self.damping, A, b)
            return
        A[:, :-n] = 0.0
        joint_pd_rows(terms.q[-n:], terms.dq[-n:], self.target, self.stiffness, self.damping, A[:, -n:], b)


@njit(cache=True)
def joint_pd_rows(q, dq, target, stiffness, damping, A, b):
    """Kernel: A = I, b = kp (q* - q) - kd dq (with target = q and kp = 0: the damping rows)."""
    n = q.shape[0]
    for i in range(n):
        for j in range(n):
            A[i, j] = 1.0 if i == j else 0.0
        b[i] = stiffness * (target[i] - q[i]) - damping * dq[i]
