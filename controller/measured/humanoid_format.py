"""What a dataset of the floating-base G1 holds beyond the arm's (docs/dataset.md, "The
floating-base G1"): its contact frame in place of a tool, the base state a humanoid's state
estimator gives, and the joint columns of its joints.

The G1 hits with a point of its own, the fixed frame ``right_palm_contact`` of the model (its
description's ``contact``, ``controller/model/robots/g1.toml``): the manifest's ``tool`` is
``{"frame": "right_palm_contact", "contact_point": [0, 0, 0]}``, the contact point at the frame's
origin; any other tool of a G1 manifest is bad input. The base state of row k is Pinocchio's
free-flyer convention: the position of the base frame in the world (m), its orientation as a unit
quaternion (x, y, z, w), and its twist (linear then angular velocity, m/s and rad/s) expressed in
the base frame itself.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.floating_base import FloatingBaseModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError, non_empty_string, numbers

G1 = ROBOTS["g1"].name
"""The manifest's ``robot`` of a G1 dataset: the G1 description's name."""
BASE_COLUMNS = (
    "base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw",
    "base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz",
)
QUATERNION = slice(BASE_COLUMNS.index("base_qx"), BASE_COLUMNS.index("base_qw") + 1)
"""The quaternion's columns within the base state."""
QUATERNION_TOLERANCE = 1e-6
"""How far from 1 a logged quaternion's norm may be (the CSV's 10 significant digits)."""


@dataclass(frozen=True)
class ContactFrame:
    """The G1's contact point: the origin of one of its fixed frames (the manifest's ``tool``)."""

    frame: str = ROBOTS[G1].contact.name

    @property
    def name(self) -> str:
        return self.frame

    def as_dict(self) -> dict:
        return {"frame": self.frame, "contact_point": [0.0, 0.0, 0.0]}


PALM = ContactFrame()


def contact_frame_from_dict(tool: dict) -> ContactFrame:
    """The manifest's ``tool`` of a G1 dataset: exactly :data:`PALM`'s description."""
    if set(tool) != {"frame", "contact_point"}:
        raise BadInputError(f"tool: a g1 dataset's tool is {PALM.as_dict()} (docs/dataset.md)")
    frame = non_empty_string(tool["frame"], "tool.frame")
    point = numbers(tool["contact_point"], 3, "tool.contact_point")
    if frame != PALM.frame or np.any(np.asarray(point) != 0.0):
        raise BadInputError(f"tool: the g1 hits with its frame {PALM.frame!r} at [0, 0, 0], not {frame!r} at "
                            f"{[round(float(x), 6) for x in point]}")
    return PALM


@functools.cache
def g1_model() -> FloatingBaseModel:
    """The G1's model, built once: its joints' order and limits are the dataset's."""
    return FloatingBaseModel(G1)


def joint_count() -> int:
    """The G1's joints (the URDF's order after the free flyer)."""
    return len(g1_model().joint_names)


def quaternion_problem(base: np.ndarray, file: str) -> str | None:
    """The first row whose base quaternion is not of unit norm, as a problem, or None."""
    norm = np.linalg.norm(base[:, QUATERNION], axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_TOLERANCE)
    if off.size == 0:
        return None
    return f"{file}: the base quaternion's norm is {norm[off[0]]:.6f} at data row {off[0] + 1}, not 1"
