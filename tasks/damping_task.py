"""Damping / regularisation task."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.model_terms import ModelTerms

from .posture_task import joint_pd_rows
from .task import Task
from impactqp.controller.model.validation import BadInputError, task_gain


class DampingTask(Task):
    """ddq = -gain dq as rows I ddq = b, one per velocity (``variables``: the model's nv, the
    arm's joints or the standing humanoid's base and joints).

    With gain 0 it is a pure Tikhonov regularisation of ddq; with gain > 0 it also damps the
    joint velocity, which keeps the redundant motion of the arm from drifting. It makes the
    Hessian of the QP positive definite.
    """

    name = "damping"

    def __init__(self, variables: int, gain: float = 1.0, weight: float = 1e-4):
        if not task_gain(weight, "damping weight") > 0.0:
            raise BadInputError("the damping task weight must be > 0")
        self.gain = task_gain(gain, "damping gain")
        self.rows = int(variables)
        self.weight = np.full(self.rows, float(weight))

    def kernel_parameters(self) -> np.ndarray:
        """The gain, then the weights (rows)."""
        return np.concatenate([[self.gain], self.weight])

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        joint_pd_rows(terms.dq, terms.dq, terms.dq, 0.0, self.gain, A, b)
