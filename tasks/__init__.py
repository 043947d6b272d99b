"""Least-squares tasks of the impact-aware QP (one class per task, see ``tasks.task``)."""

from .com_task import CentreOfMassTask
from .contact_approach_task import ContactApproachTask
from .damping_task import DampingTask
from .frame_task import FrameTask
from .posture_task import PostureTask
from .surface_offset_task import SurfaceOffsetTask
from .task import ORIENTATION_PARAMETERS, OrientationHold, Task, TaskRows

__all__ = [
    "Task", "TaskRows", "FrameTask", "ContactApproachTask", "PostureTask", "DampingTask", "SurfaceOffsetTask",
    "CentreOfMassTask", "OrientationHold", "ORIENTATION_PARAMETERS",
]
