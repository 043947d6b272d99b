"""What a dataset holds of its robot, read from the robot's description (docs/dataset.md): the
columns of a trial CSV and the manifest's ``tool`` of a robot that carries none.

A trial CSV has the columns ``t``, then for a floating base (``RobotDescription.floating``) its
state :data:`BASE_COLUMNS`, then per quantity (q, dq, tau, dq_cmd) one column per joint of the
description (``joints``, in order). The base state of row k is Pinocchio's free-flyer
convention: the position of the base frame in the world (m), its orientation as a unit
quaternion (x, y, z, w), and its twist (linear then angular velocity, m/s and rad/s) expressed in
the base frame itself. A fixed-base robot has no base columns.

A floating-base robot carries no tool (``choice.RobotChoice``): it hits with its own contact point,
its description's ``contact`` (the G1: ``right_palm_contact``, ``controller/model/robots/g1.toml``).
The manifest's ``tool`` is then ``{"frame": <contact name>, "contact_point": [0, 0, 0]}``, the
contact point at that frame's origin (:class:`ContactFrame`); any other tool is bad input.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.model.robot_description import RobotDescription, robot_description
from impactqp.controller.model.validation import BadInputError, non_empty_string, numbers

BASE_COLUMNS = (
    "base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw",
    "base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz",
)
QUATERNION = slice(BASE_COLUMNS.index("base_qx"), BASE_COLUMNS.index("base_qw") + 1)
"""The quaternion's columns within the base state."""
QUATERNION_TOLERANCE = 1e-6
"""How far from 1 a logged quaternion's norm may be (the CSV's 10 significant digits)."""
JOINT_QUANTITIES = ("q", "dq", "tau", "dq_cmd")
"""The per-joint quantities of a trial CSV, in column order."""


def base_columns(robot: str | Path | RobotDescription) -> tuple[str, ...]:
    """The base state's columns of a trial CSV of ``robot``: :data:`BASE_COLUMNS` for a floating
    base, none for a fixed one."""
    return BASE_COLUMNS if robot_description(robot).floating else ()


def trial_columns(robot: str | Path | RobotDescription) -> list[str]:
    """The columns of a trial CSV of ``robot`` (a description, its name or its file): t, a
    floating base's state, then per quantity (q, dq, tau, dq_cmd) one column per joint."""
    joints = len(robot_description(robot).joints)
    return ["t", *base_columns(robot), *(f"{name}{i}" for name in JOINT_QUANTITIES for i in range(1, joints + 1))]


@dataclass(frozen=True)
class ContactFrame:
    """The contact point of a robot that carries no tool: the origin of its fixed frame
    ``frame`` (its description's ``contact``; the manifest's ``tool``)."""

    frame: str

    @classmethod
    def of(cls, robot: str | Path | RobotDescription) -> ContactFrame:
        """The contact frame of ``robot``'s description; bad input for a robot without one."""
        description = robot_description(robot)
        if description.contact is None:
            raise BadInputError(f"the {description.name} has no contact point of its own (its description's contact)")
        return cls(description.contact.name)

    @property
    def name(self) -> str:
        return self.frame

    def as_dict(self) -> dict:
        return {"frame": self.frame, "contact_point": [0.0, 0.0, 0.0]}


def contact_frame_from_dict(tool: dict, robot: str | Path | RobotDescription) -> ContactFrame:
    """The manifest's ``tool`` of a dataset of ``robot`` (a robot that carries no tool): exactly
    its :class:`ContactFrame`'s description."""
    contact, name = ContactFrame.of(robot), robot_description(robot).name
    if set(tool) != {"frame", "contact_point"}:
        raise BadInputError(f"tool: a {name} dataset's tool is {contact.as_dict()} (docs/dataset.md)")
    frame = non_empty_string(tool["frame"], "tool.frame")
    point = numbers(tool["contact_point"], 3, "tool.contact_point")
    if frame != contact.frame or np.any(np.asarray(point) != 0.0):
        raise BadInputError(f"tool: the {name} hits with its frame {contact.frame!r} at [0, 0, 0], not {frame!r} at "
                            f"{[round(float(x), 6) for x in point]}")
    return contact


def quaternion_problem(base: np.ndarray, file: str) -> str | None:
    """The first row whose base quaternion is not of unit norm, as a problem, or None."""
    norm = np.linalg.norm(base[:, QUATERNION], axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_TOLERANCE)
    if off.size == 0:
        return None
    return f"{file}: the base quaternion's norm is {norm[off[0]]:.6f} at data row {off[0] + 1}, not 1"
