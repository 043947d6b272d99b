"""Frame task: position and orientation of the contact frame (or of another frame the model
terms carry, e.g. the humanoid's torso)."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import finite_array, finite_vector, task_gain

from .task import Task, critical_damping, rotation_error


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
            None if target_rotation is None else finite_array(target_rotation, (3, 3), "target_rotation")
        )
        self.stiffness = task_gain(stiffness, "frame stiffness")
        self.damping = critical_damping(self.stiffness) if damping is None else task_gain(damping, "frame damping")
        self.weight = np.repeat(
            [task_gain(position_weight, "position_weight"), task_gain(orientation_weight, "orientation_weight")], 3
        )
        self._configured = (self.target_position is not None, self.target_rotation is not None)

    def _state(self, terms: ModelTerms) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(p, R, J6, dJ6 dq) of the task's frame."""
        if self.frame is None:
            return terms.contact_point, terms.contact_rotation, terms.J6, terms.dJ6_dq
        return terms.frame(self.frame)

    def reset(self, terms: ModelTerms) -> None:
        position, rotation, _, _ = self._state(terms)
        if not self._configured[0]:
            self.target_position = position.copy()
        if not self._configured[1]:
            self.target_rotation = rotation.copy()

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        position, rotation, J6, dJ6_dq = self._state(terms)
        A[:] = J6
        b[:3] = self.target_position - position
        b[3:] = rotation_error(self.target_rotation, rotation)
        b *= self.stiffness
        b -= self.damping * (J6 @ terms.dq) + dJ6_dq
