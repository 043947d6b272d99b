"""Frame task: position and orientation of the contact frame."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.robot import ModelTerms
from impactqp.controller.model.validation import finite_array, finite_vector, task_gain

from .task import Task, critical_damping, rotation_error


class FrameTask(Task):
    """Drive the contact frame to a target pose with a PD law in task space.

    Desired frame acceleration (world axes, linear; angular):

        a* = [kp (p* - p) - kd v;  kp log(R* R^T) - kd w],   [v; w] = J6 dq

    and the rows J6 ddq = a* - dJ6 dq (3 position rows weighted ``position_weight``, 3
    orientation rows weighted ``orientation_weight``). kd defaults to 2 sqrt(kp). A target left
    as None is the pose at ``reset``.
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
    ):
        self.target_position = (
            None if target_position is None else finite_vector(target_position, 3, "target_position")
        )
        self.target_rotation = (
            None if target_rotation is None else finite_array(target_rotation, (3, 3), "target_rotation")
        )
        self.stiffness = task_gain(stiffness, "frame stiffness")
        self.damping = critical_damping(self.stiffness) if damping is None else task_gain(damping, "frame damping")
        self.weight = np.repeat(
            [task_gain(position_weight, "position_weight"), task_gain(orientation_weight, "orientation_weight")], 3
        )
        self._configured = (self.target_position is not None, self.target_rotation is not None)

    def reset(self, terms: ModelTerms) -> None:
        if not self._configured[0]:
            self.target_position = terms.contact_point.copy()
        if not self._configured[1]:
            self.target_rotation = terms.contact_rotation.copy()

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        A[:] = terms.J6
        b[:3] = self.target_position - terms.contact_point
        b[3:] = rotation_error(self.target_rotation, terms.contact_rotation)
        b *= self.stiffness
        b -= self.damping * (terms.J6 @ terms.dq) + terms.dJ6_dq
