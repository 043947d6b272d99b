"""Frame task: position and orientation of the contact frame (or of another frame the model
terms carry, e.g. the humanoid's torso)."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import finite_vector, rotation_matrix, task_gain

from .task import Task, critical_damping, rotation_log

FRAME_PARAMETERS = 20
"""The size of a frame task's ``kernel_parameters``: kp, kd, p* (3), R* (9, row by row), the weights (6)."""


class FrameTask(Task):
    """Drive the contact frame (``frame`` None) or the frame ``terms.frame(frame)`` of the model
    terms to a target pose with a PD law in task space.

    Desired frame acceleration (world axes, linear; angular):

        a* = [kp (p* - p) - kd v;  kp log(R* R^T) - kd w],   [v; w] = J6 dq

    and the rows J6 ddq = a* - dJ6 dq (3 position rows weighted ``position_weight``, 3
    orientation rows weighted ``orientation_weight``; a weight 0 leaves that part free, e.g. the
    torso's orientation alone). kd defaults to 2 sqrt(kp). A target left as None is the pose at
    ``reset``.
    """

    name = "frame"
    rows = 6

    def __init__(
        self,
        target_position=None,
        target_rotation=None,
        stiffness: float = 100.0,
        damping: float | None = None,
        position_weight: float = 1.0,
        orientation_weight: float = 1.0,
        frame: str | None = None,
    ):
        self.frame = frame
        if frame is not None:
            self.name = f"frame[{frame}]"
        self.target_position = (
            None if target_position is None else finite_vector(target_position, 3, "target_position")
        )
        self.target_rotation = (
            None if target_rotation is None else rotation_matrix(target_rotation, "target_rotation")
        )
        self.stiffness = task_gain(stiffness, "frame stiffness")
        self.damping = critical_damping(self.stiffness) if damping is None else task_gain(damping, "frame damping")
        self.weight = np.repeat(
            [task_gain(position_weight, "position_weight"), task_gain(orientation_weight, "orientation_weight")], 3
        )
        self._configured = (self.target_position is not None, self.target_rotation is not None)

    def frame_state(self, terms: ModelTerms) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(p, R, J6, dJ6 dq) of the task's frame."""
        if self.frame is None:
            return terms.contact_point, terms.contact_rotation, terms.J6, terms.dJ6_dq
        return terms.frame(self.frame)

    def reset(self, terms: ModelTerms) -> None:
        position, rotation, _, _ = self.frame_state(terms)
        if not self._configured[0]:
            self.target_position = position.copy()
        if not self._configured[1]:
            self.target_rotation = rotation.copy()

    def kernel_parameters(self) -> np.ndarray:
        """kp, kd, p*, R* (row by row) and the weights (6): ``FRAME_PARAMETERS`` values."""
        return np.concatenate([[self.stiffness, self.damping], self.target_position, self.target_rotation.ravel(), self.weight])

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        frame_rows(self.frame_state(terms), terms.dq, self.kernel_parameters()[:14], A, b)


@njit(cache=True)
def frame_rows(frame, dq, parameters, A, b):
    """Kernel: A = J6 and b = kp [p* - p; log(R* R^T)] - kd J6 v - dJ6 v for frame = (p, R, J6,
    dJ6 v) and parameters = (kp, kd, p*, R* row by row)."""
    position, rotation, J6, drift = frame
    kp, kd = parameters[0], parameters[1]
    rotation_log(parameters[5:14].reshape((3, 3)), rotation, b[3:6])
    for i in range(3):
        b[i] = parameters[2 + i] - position[i]
    rate = J6 @ dq  # the product and the sums of the numpy statement
    for i in range(6):
        b[i] *= kp
        b[i] -= kd * rate[i] + drift[i]
    A[:, :] = J6
