"""Robot descriptions by name: the URDF a robot is built from, its joints, frames, datasheet
limits and named impact postures (docs/robots.md).

Both built-in arms come with their URDF from a maintained package, never a copied file:

- ``panda``: the Franka Emika Panda (FER) of ``example-robot-data``;
- ``fr3``: the Franka Research 3 of franka_description, shipped as package data by
  ``franky-sim`` (``franky_sim/assets/fr3.urdf``). Only its location is looked up; the package
  itself is not imported (it loads MuJoCo, which the ground never does).

Both URDFs carry the Franka Hand (hand and finger links). The model locks the fingers; a tool
that replaces the hand (``ToolDescription.replaces_hand``) removes the hand's inertia and the
fingers from the URDF before the model and the MuJoCo scene load it (:func:`model_urdf`).
"""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .postures import FR3_POSTURES, PANDA_POSTURES, ImpactPosture
from .tool_description import ToolDescription
from .validation import BadInputError


def panda_urdf_path() -> Path:
    """Path of the Panda URDF shipped by the ``example-robot-data`` package."""
    import example_robot_data  # imported on first use: it locates its data at import time

    subpath = "panda_description/urdf/panda.urdf"
    return (Path(example_robot_data.getModelPath(subpath)) / subpath).resolve()


def panda_mesh_dir() -> Path:
    """The directory of the Panda's STL collision meshes (MuJoCo reads STL, not the DAE visuals)."""
    return panda_urdf_path().parent.parent / "meshes" / "collision"


def _franky_sim_assets() -> Path:
    spec = importlib.util.find_spec("franky_sim")  # locates the package without importing it
    if spec is None or spec.origin is None:
        raise BadInputError("the fr3 robot needs the franky-sim package (pip install franky-sim)")
    return Path(spec.origin).parent / "assets"


def fr3_urdf_path() -> Path:
    """Path of franka_description's FR3 URDF as ``franky-sim`` ships it."""
    return _franky_sim_assets() / "fr3.urdf"


def fr3_mesh_dir() -> Path:
    """The directory of the FR3's STL collision meshes shipped beside the URDF."""
    return _franky_sim_assets() / "meshes"


def _limit(values) -> np.ndarray:
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class RobotDescription:
    """A 7-DoF arm carrying a Franka Hand.

    ``urdf_path`` and ``mesh_dir`` locate its URDF and STL collision meshes; ``joints`` are the
    moving joints in order, ``finger_joints`` / ``finger_links`` the hand's fingers (locked by
    the model, welded in the scene), ``hand_frame`` the hand's link (its frame is the ``"hand"``
    tool frame) and ``flange_frame`` the flange link (the ``"flange"`` tool frame). The limits are
    the datasheet's, per joint: positions ``q_min``/``q_max`` (rad), velocity ``dq_max`` (rad/s),
    acceleration ``ddq_max`` (rad/s^2), jerk ``dddq_max`` (rad/s^3) and torque ``tau_max`` (N m).
    ``postures`` are named impact postures on the default wall for the ``impact_tip`` tool.
    """

    name: str
    urdf_path: Callable[[], Path]
    mesh_dir: Callable[[], Path]
    joints: tuple[str, ...]
    finger_joints: tuple[str, ...]
    finger_links: tuple[str, ...]
    hand_frame: str
    flange_frame: str
    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    ddq_max: np.ndarray
    dddq_max: np.ndarray
    tau_max: np.ndarray
    postures: Mapping[str, ImpactPosture]

    def posture(self, name: str) -> ImpactPosture:
        """The named impact posture ``name`` of this robot."""
        try:
            return self.postures[name]
        except KeyError:
            raise BadInputError(
                f"unknown posture {name!r} for the {self.name}; known postures: {', '.join(self.postures)}"
            ) from None

    def frame_of(self, tool: ToolDescription) -> str:
        """The name of the URDF frame the tool is fixed to."""
        return self.hand_frame if tool.frame == "hand" else self.flange_frame


def _franka_arm(prefix: str) -> dict:
    """The joint, finger and frame names shared by franka_description's arms (``prefix`` + name)."""
    return dict(
        joints=tuple(f"{prefix}_joint{i}" for i in range(1, 8)),
        finger_joints=(f"{prefix}_finger_joint1", f"{prefix}_finger_joint2"),
        finger_links=(f"{prefix}_leftfinger", f"{prefix}_rightfinger"),
        hand_frame=f"{prefix}_hand",
        flange_frame=f"{prefix}_link8",
    )


PANDA = RobotDescription(
    name="panda",
    urdf_path=panda_urdf_path,
    mesh_dir=panda_mesh_dir,
    **_franka_arm("panda"),
    # Franka's FER datasheet (docs/robots.md).
    q_min=_limit([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]),
    q_max=_limit([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]),
    dq_max=_limit([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]),
    ddq_max=_limit([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
    dddq_max=_limit([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
    tau_max=_limit([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
    postures=PANDA_POSTURES,
)

FR3 = RobotDescription(
    name="fr3",
    urdf_path=fr3_urdf_path,
    mesh_dir=fr3_mesh_dir,
    **_franka_arm("fr3"),
    # Franka's "Limits for Franka Research 3 (FR3)" table (docs/robots.md).
    q_min=_limit([-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508]),
    q_max=_limit([2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508]),
    dq_max=_limit([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
    ddq_max=_limit([10.0] * 7),
    dddq_max=_limit([5000.0] * 7),
    tau_max=_limit([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
    postures=FR3_POSTURES,
)

ROBOTS: dict[str, RobotDescription] = {robot.name: robot for robot in (PANDA, FR3)}


def robot_description(robot: str | RobotDescription) -> RobotDescription:
    """The description ``robot``: returned as is, or looked up by name in :data:`ROBOTS`."""
    if isinstance(robot, RobotDescription):
        return robot
    try:
        return ROBOTS[robot]
    except (KeyError, TypeError):
        raise BadInputError(f"unknown robot {robot!r}; choose from {', '.join(ROBOTS)}") from None


def model_urdf(robot: RobotDescription, tool: ToolDescription, urdf_path: str | Path | None = None) -> str:
    """The robot's URDF text as the model and the scene load it: unchanged, or, when the tool
    replaces the Franka Hand, without the fingers (links and joints) and without the hand link's
    inertial, visual and collision elements (the link stays: its frame is the ``"hand"`` frame)."""
    path = Path(urdf_path) if urdf_path is not None else robot.urdf_path()
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise BadInputError(f"cannot read the {robot.name} URDF {path}: {exc}") from None
    if not tool.replaces_hand:
        return text
    root = ET.fromstring(text)
    for link in root.findall("link"):
        if link.get("name") in robot.finger_links:
            root.remove(link)
        elif link.get("name") == robot.hand_frame:
            for child in list(link):
                link.remove(child)
    for joint in root.findall("joint"):
        if joint.get("name") in robot.finger_joints:
            root.remove(joint)
    return ET.tostring(root, encoding="unicode")
