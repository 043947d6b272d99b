"""The output of one control cycle (``Command``), its ``Status``, and the controller's memory of
the previous command."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from impactqp.controller.model.robot import PandaModel


class Status(str, Enum):
    """Why a command is what it is. A ``str``: each member equals its value (``Status.OK ==
    "ok"``), prints as it and is written to JSON as it."""

    OK = "ok"
    VELOCITY_CLIPPED = "ok_velocity_clipped"
    FALLBACK_INFEASIBLE = "fallback_infeasible"
    FALLBACK_INVALID_STATE = "fallback_invalid_state"
    FALLBACK_SINGULAR = "fallback_singular_posture"
    FALLBACK_SOLVER_ERROR = "fallback_solver_error"
    IMPACT_BRAKE = "impact_brake"

    def __str__(self) -> str:
        return self.value

    @property
    def is_fallback(self) -> bool:
        """Whether the command stands in for a QP solution that could not be had (the impact
        brake is the controller's planned behaviour after a noticed impact, not a fallback)."""
        return self not in (Status.OK, Status.VELOCITY_CLIPPED, Status.IMPACT_BRAKE)


@dataclass(eq=False, repr=False, slots=True)
class Command:
    """The output of one control cycle for a kinematic-controlled robot.

    ``predicted_jump`` is the joint-velocity jump an impact would cause at the commanded
    velocity (dq- = dq_cmd) with the controller's prediction model, and
    ``predicted_post_impact_velocity`` = dq_cmd + predicted_jump; both are zero when the
    controller has no impact model or the state was unusable. ``phase`` is the phase of the
    impact session that issued the command (``docs/robot-loop.md``). Slotted: one is made per
    cycle, so it must cost little.
    """

    ddq: np.ndarray
    dq_cmd: np.ndarray
    q_cmd: np.ndarray
    status: Status
    active_constraints: list[str]
    violated_constraints: list[str]
    predicted_jump: np.ndarray
    predicted_post_impact_velocity: np.ndarray
    impact_constraints_active: bool = False
    solver: str = ""
    message: str = ""
    phase: str = "approach"

    @property
    def is_fallback(self) -> bool:
        return Status(self.status).is_fallback

    def __repr__(self) -> str:
        return f"Command(status={self.status!r}, phase={self.phase!r}, dq_cmd={self.dq_cmd!r})"


DQ_MAX, Q_MIN, Q_MAX, DDQ_MAX, JERK_STEP = range(5)
"""Rows of ``command_limits``."""


def command_limits(robot: PandaModel, ddq_max: np.ndarray, jerk_step: np.ndarray) -> np.ndarray:
    """The joint limits every command keeps, stacked (5, one per joint) for the compiled kernels: rows
    dq_max, q_min, q_max, ddq_max and jerk_step = dddq_max dt (indices DQ_MAX ... JERK_STEP)."""
    return np.vstack([robot.dq_max, robot.q_min, robot.q_max, ddq_max, jerk_step]).astype(float)


@dataclass
class CommandMemory:
    """The previous command, for continuity (jerk limits) and for unusable states: copies of
    what the caller was given, which it may change. ``sent_dq_cmd`` is the dq_cmd array the
    caller was given (a loop that feeds it back is recognised by identity)."""

    q_cmd: np.ndarray | None
    dq_cmd: np.ndarray
    ddq: np.ndarray
    sent_dq_cmd: np.ndarray | None = None
