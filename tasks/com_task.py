"""Centre-of-mass task: hold (or move) the robot's centre of mass with a PD law."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.validation import finite_vector, task_gain
from impactqp.controller.model.model_terms import ModelTerms

from .task import Task, critical_damping


class CentreOfMassTask(Task):
    """ddc* = kp (c* - c) - kd dc, dc = Jcom v, as the 3 rows Jcom dv = ddc* - dJcom v
    (dJcom v: the CoM acceleration at dv = 0), kd = 2 sqrt(kp) by default, one weight per
    world axis (x, y, z). A target left as None is the centre of mass at ``reset``.

    The error e = c* - c(q) has the derivative de/dt = -Jcom v, so the rows are those of the
    frame task with the CoM's Jacobian.
    """

    name = "com"
    rows = 3

    def __init__(self, target=None, stiffness: float = 100.0, damping: float | None = None, weight=(1.0, 1.0, 1.0)):
        self.target = None if target is None else finite_vector(target, 3, "the centre-of-mass target")
        self._target_configured = self.target is not None
        self.stiffness = task_gain(stiffness, "centre-of-mass stiffness")
        self.damping = (
            critical_damping(self.stiffness) if damping is None else task_gain(damping, "centre-of-mass damping")
        )
        self.weight = axis_weights(weight)

    def hold(self, target, stiffness: float, weight) -> None:
        """A new target c*, stiffness kp (critically damped: kd = 2 sqrt(kp)) and weights, kept
        by later resets."""
        self.target = finite_vector(target, 3, "the centre-of-mass target")
        self._target_configured = True
        self.stiffness = task_gain(stiffness, "centre-of-mass stiffness")
        self.damping = critical_damping(self.stiffness)
        self.weight = axis_weights(weight)

    def error(self, terms: ModelTerms) -> np.ndarray:
        """e = c* - c."""
        return self.target - terms.com

    def reset(self, terms: ModelTerms) -> None:
        if not self._target_configured:
            self.target = terms.com.copy()

    def kernel_parameters(self) -> np.ndarray:
        """kp, kd, c* and the weights (3)."""
        return np.concatenate([[self.stiffness, self.damping], self.target, self.weight])

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        com_rows(terms.Jcom, terms.dq, terms.com, terms.dJcom_dq, self.target, (self.stiffness, self.damping), A, b)


def axis_weights(weight) -> np.ndarray:
    """The task's three weights (x, y, z), each checked."""
    weight = finite_vector(weight, 3, "centre-of-mass weight")
    return np.array([task_gain(w, "centre-of-mass weight") for w in weight])


@njit(cache=True)
def com_rows(Jcom, dq, com, dJcom_dq, target, gains, A, b):
    """Kernel: A = Jcom, b = kp (c* - c) - kd Jcom v - dJcom v, gains = (kp, kd)."""
    kp, kd = gains
    for i in range(3):
        rate = 0.0
        for j in range(dq.shape[0]):
            A[i, j] = Jcom[i, j]
            rate += Jcom[i, j] * dq[j]
        b[i] = kp * (target[i] - com[i]) - kd * rate - dJcom_dq[i]
