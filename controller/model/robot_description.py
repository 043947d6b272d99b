"""Robot descriptions: a robot is data, one file (docs/robots.md).

A :class:`RobotDescription` says everything the model, the controller and the simulation need
to know of a robot: where its URDF and collision meshes are, whether its base is fixed or
floating, its moving joints in order and their limits, the frames a tool may be fixed to, the
gripper whose fingers the model locks, the robot's own contact point (a robot that carries no
tool), the contacts it holds (the soles of a standing humanoid: polygon, depth, friction), and
its named postures (an arm's impact postures) or stances (where a humanoid's feet stand). The
held contacts and stances are read by ``held_contact_description``, the fields of a file checked
by ``description_fields``.

The built-in robots (:data:`ROBOTS`: ``panda``, ``fr3``, ``ur5``, ``g1``) are TOML files shipped
with the package (``controller/model/robots/``); :func:`robot_description` takes one of their
names or the path of the user's own file (TOML, JSON or YAML, the same keys). A file never
holds a copy of a URDF: it names a file beside it or a file inside an installed package
(``{package = "example-robot-data", path = ...}``). Limits missing from the file are read from
the URDF's ``<limit>`` elements (position, velocity, torque); acceleration and jerk limits are
not in a URDF and are required (one number for every joint, or one per joint).

The model locks the fingers; a tool that replaces the hand (``ToolDescription.replaces_hand``)
removes the hand's inertia and the fingers from the URDF before the model and the MuJoCo scene
load it (:func:`model_urdf`).
"""

from __future__ import annotations

import importlib.util
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .description_fields import name_field, named_tables_field, names_field, table_field
from .files import read_mapping, read_text
from .held_contact_description import MAX_CONTACT_LENGTH, HeldContact, Stance, held_contacts_of, stances_of
from .postures import DEFAULT_WALL, ImpactPosture
from .tool_description import ToolDescription
from .validation import BadInputError, finite_vector, number_in_range, rigid_body_moments

__all__ = [
    "HeldContact", "PANDA", "RobotContact", "RobotDescription", "ROBOTS", "Stance", "load_robot_description",
    "model_urdf", "robot_description",
]

BASES = ("fixed", "floating")
ROBOT_KEYS = {
    "name", "base", "joints", "default_posture", "urdf", "meshes", "tool_frames", "hand", "limits",
    "contact", "held_contacts", "postures", "stances", "frames", "nominal_posture",
}
LIMIT_KEYS = ("q_min", "q_max", "dq_max", "ddq_max", "dddq_max", "tau_max")
URDF_LIMITS = {"q_min": "lower", "q_max": "upper", "dq_max": "velocity", "tau_max": "effort"}
LIMIT_RANGES = {
    "dq_max": (0.01, 100.0, "rad/s"),
    "ddq_max": (0.1, 1e5, "rad/s^2"),
    "dddq_max": (1.0, 1e8, "rad/s^3"),
    "tau_max": (0.1, 1e5, "N m"),
}
"""The range of each rate and torque limit (low, high, unit; a prismatic joint's in m and N):
wide around any robot's (a Franka's 2.6 rad/s, 15 rad/s^2, 7500 rad/s^3 and 87 N m; the G1's
ankle, 3 rad/s^2), narrow enough to refuse a value in other units or one that no approach or
search can use (a speed of 1e-3 rad/s, a torque of 1e308 N m)."""
BUILTIN_DIR = Path(__file__).parent / "robots"
ROBOT_FILE_SUFFIXES = (".toml", ".json", ".yaml", ".yml")
"""The suffixes of a robot description file (``files.read_mapping`` reads each)."""


@dataclass(frozen=True)
class FileSource:
    """Where a URDF or a mesh directory is: ``path`` inside the installed Python ``package``
    (``example-robot-data`` resolves through its model path), or, with no package, a path
    relative to the description file's folder ``base``."""

    path: str
    package: str | None = None
    base: Path | None = None

    def resolve(self, robot: str) -> Path:
        if self.package is None:
            path = Path(self.path)
            return path if path.is_absolute() or self.base is None else self.base / path
        if self.package == "example-robot-data":
            import example_robot_data  # imported on first use: it locates its data at import time

            return (Path(example_robot_data.getModelPath(self.path)) / self.path).resolve()
        # locate the package without importing it (franky-sim would load MuJoCo)
        spec = importlib.util.find_spec(self.package.replace("-", "_"))
        if spec is None or spec.origin is None:
            raise BadInputError(f"the {robot} robot needs the {self.package} package (pip install {self.package})")
        return Path(spec.origin).parent / self.path


@dataclass(frozen=True, eq=False)
class RobotContact:
    """The robot's own contact point (a robot that carries no tool): frame ``name`` at
    ``offset`` (m) from ``frame``, with that frame's orientation; ``joints``, the joints that
    move it in a scripted approach (a humanoid's arm; empty: every joint)."""

    name: str
    frame: str
    offset: np.ndarray
    joints: tuple[str, ...] = ()


def _read_only(values) -> np.ndarray:
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class RobotDescription:
    """One robot (module docstring). ``joints`` are the moving joints in order (a floating base's
    coordinates come before them); the limits are per joint: positions ``q_min``/``q_max`` (rad),
    velocity ``dq_max`` (rad/s), acceleration ``ddq_max`` (rad/s^2), jerk ``dddq_max`` (rad/s^3)
    and torque ``tau_max`` (N m), read-only arrays. ``tool_frames`` maps a tool's ``frame``
    (``"hand"``, ``"flange"``) to a URDF frame; ``hand_frame``, ``finger_joints`` and
    ``finger_links`` describe the gripper (empty without one). ``frames`` names further URDF
    frames whose state the model terms carry (``ModelTerms.frame(name)``: a humanoid's torso,
    ``{torso = "torso_link"}``). ``nominal_posture`` maps joints to the angles (rad; the others
    0) that a floating base's stance solver pulls towards. ``source`` is the file the
    description was read from."""

    name: str
    base: str
    urdf: FileSource
    meshes: FileSource
    joints: tuple[str, ...]
    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    ddq_max: np.ndarray
    dddq_max: np.ndarray
    tau_max: np.ndarray
    tool_frames: Mapping[str, str] = field(default_factory=dict)
    hand_frame: str = ""
    finger_joints: tuple[str, ...] = ()
    finger_links: tuple[str, ...] = ()
    contact: RobotContact | None = None
    held_contacts: tuple[HeldContact, ...] = ()
    postures: Mapping[str, ImpactPosture] = field(default_factory=dict)
    stances: Mapping[str, Stance] = field(default_factory=dict)
    default_posture: str = ""
    frames: Mapping[str, str] = field(default_factory=dict)
    nominal_posture: Mapping[str, float] = field(default_factory=dict)
    source: Path | None = None

    @property
    def floating(self) -> bool:
        """Whether the base is floating (a free-flyer root before the joints)."""
        return self.base == "floating"

    @property
    def flange_frame(self) -> str:
        return self.tool_frames.get("flange", "")

    def urdf_path(self) -> Path:
        """The robot's URDF file."""
        return self.urdf.resolve(self.name)

    def mesh_dir(self) -> Path:
        """The directory of its collision meshes."""
        return self.meshes.resolve(self.name)

    def posture(self, name: str) -> ImpactPosture:
        """The named impact posture ``name`` of this robot."""
        try:
            return self.postures[name]
        except KeyError:
            raise BadInputError(
                f"unknown posture {name!r} for the {self.name}; known postures: {', '.join(self.postures) or 'none'}"
            ) from None

    def frame_of(self, tool: ToolDescription) -> str:
        """The name of the URDF frame the tool is fixed to."""
        try:
            return self.tool_frames[tool.frame]
        except KeyError:
            raise BadInputError(
                f"the {self.name} has no {tool.frame!r} frame for the tool {tool.name!r}; "
                f"its tool frames: {', '.join(self.tool_frames) or 'none'}"
            ) from None


# ---------------------------------------------------------------------- reading a description
def _source(value, key: str, base: Path | None) -> FileSource:
    if isinstance(value, str) and value:
        return FileSource(value, None, base)
    if isinstance(value, dict) and set(value) == {"package", "path"}:
        return FileSource(name_field(value["path"], f"{key}.path"), name_field(value["package"], f"{key}.package"))
    raise BadInputError(f"'{key}' must be a path or a table {{package = ..., path = ...}}")


def _urdf_joints(urdf_text: str, robot: str) -> dict[str, dict[str, float]]:
    """Every moving joint of the URDF (revolute, prismatic) in document order, with the
    attributes of its ``<limit>``."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as error:
        raise BadInputError(f"the {robot} URDF is not valid XML: {error}") from None
    joints = {}
    for joint in root.iter("joint"):
        if joint.get("type") in ("revolute", "prismatic"):
            limit = joint.find("limit")
            attributes = {} if limit is None else limit.attrib
            joints[joint.get("name")] = {k: attributes.get(k) for k in ("lower", "upper", "velocity", "effort")}
    return joints


def urdf_number(text: str, what: str) -> float:
    """A URDF attribute's number; BadInputError naming ``what`` when it is not one."""
    try:
        return float(text)
    except ValueError:
        raise BadInputError(f"{what} is not a number: {text!r}") from None


def check_link_inertias(urdf_text: str, robot: str) -> None:
    """BadInputError for a link whose ``<inertia>`` is not a physical rotational inertia: an entry
    that is not a finite number, a negative principal moment, or principal moments A <= B <= C
    with A + B < C (the triangle inequality every rigid body's moments keep, which MuJoCo's
    scene also demands of the file's inertias as they are)."""
    root = ET.fromstring(urdf_text)
    for link in root.iter("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        name = link.get("name")
        entries = [urdf_number(inertia.get(k, "0"), f"the {robot} URDF's {k} of link {name}")
                   for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")]
        if not np.all(np.isfinite(entries)):
            raise BadInputError(f"the {robot} URDF's inertia of link {name} is not finite")
        xx, xy, xz, yy, yz, zz = entries
        moments = np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
        slack = 1e-9 * max(float(moments[2]), 0.0)
        if not rigid_body_moments(moments, slack):
            raise BadInputError(
                f"the {robot} URDF's inertia of link {name} is not a rigid body's (principal moments "
                f"{', '.join(f'{m:.4g}' for m in moments)} kg m^2: each must be >= 0 and A + B >= C)"
            )


def _limits(table: Mapping, joints: tuple[str, ...], urdf: dict | None, robot: str) -> dict[str, np.ndarray]:
    """The six limit arrays: each from the file (a number for every joint or one per joint) or,
    for position, velocity and torque, from the URDF (``urdf``: its joints' limit attributes)."""
    limits = {}
    for key in LIMIT_KEYS:
        value = table.get(key)
        if value is None:
            attribute = URDF_LIMITS.get(key)
            if attribute is None:
                raise BadInputError(f"the {robot} description's [limits] needs {key} (a URDF has none)")
            texts = [urdf[j][attribute] for j in joints]
            if None in texts:
                raise BadInputError(f"the {robot} URDF gives no {attribute} limit for every joint: set {key}")
            value = [urdf_number(t, f"the {robot} URDF's {attribute} limit of joint {j}") for t, j in zip(texts, joints)]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value] * len(joints)
        limits[key] = _read_only(finite_vector(value, len(joints), f"the {robot} limit {key}"))
    for key, (low, high, unit) in LIMIT_RANGES.items():
        if not np.all(limits[key] > 0.0):
            raise BadInputError(f"the {robot} limit {key} must be > 0 for every joint")
        outside = [j for j, x in zip(joints, limits[key]) if not low <= x <= high]
        if outside:
            raise BadInputError(
                f"the {robot} limit {key} must lie in [{low:g}, {high:g}] {unit} for every joint (a robot's, in SI "
                f"units), got {limits[key][joints.index(outside[0])]:g} for {outside[0]}"
            )
    if not np.all(limits["q_min"] < limits["q_max"]):
        raise BadInputError(f"the {robot} limits need q_min < q_max for every joint")
    return limits


def _postures_within(postures: Mapping[str, ImpactPosture], joints: tuple[str, ...], limits: dict, robot: str) -> None:
    """BadInputError naming the first posture with a joint outside its position limits."""
    for name, posture in postures.items():
        outside = np.flatnonzero((posture.q < limits["q_min"]) | (posture.q > limits["q_max"]))
        if outside.size:
            i = int(outside[0])
            raise BadInputError(
                f"the {robot} posture {name}: {joints[i]} = {posture.q[i]:.4f} rad lies outside its limits "
                f"[{limits['q_min'][i]:.4f}, {limits['q_max'][i]:.4f}]"
            )


def _postures(table: Mapping, n: int, robot: str) -> dict[str, ImpactPosture]:
    postures = {}
    for name, entry in table.items():
        entry = table_field(table, name, {"q", "description"}, f"the {robot} posture")
        if not isinstance(entry.get("description", ""), str):
            raise BadInputError(f"the {robot} posture {name} description must be text")
        q = _read_only(finite_vector(entry.get("q"), n, f"the {robot} posture {name} q"))
        postures[name] = ImpactPosture(name, q, entry.get("description", ""), DEFAULT_WALL)
    return postures


def description_from_mapping(data: Mapping, base: Path | None = None, source: Path | None = None) -> RobotDescription:
    """The description of the keys of a robot file (module docstring); relative paths are taken
    from the folder ``base``."""
    unknown = sorted(set(data) - ROBOT_KEYS)
    if unknown:
        raise BadInputError(f"unknown robot description keys {', '.join(unknown)}; known: {', '.join(sorted(ROBOT_KEYS))}")
    robot = name_field(data.get("name"), "the robot's name")
    kind = data.get("base", "fixed")
    if kind not in BASES:
        raise BadInputError(f"the {robot} base must be one of {', '.join(BASES)}, got {kind!r}")
    for key in ("urdf", "meshes"):
        if key not in data:
            raise BadInputError(f"the {robot} description needs '{key}'")
    urdf, meshes = _source(data["urdf"], "urdf", base), _source(data["meshes"], "meshes", base)
    hand = table_field(data, "hand", {"frame", "finger_joints", "finger_links"}, f"the {robot}")
    fingers = names_field(hand.get("finger_joints", []), f"the {robot} finger_joints")
    limit_table = table_field(data, "limits", set(LIMIT_KEYS), f"the {robot}")
    urdf_joints = None
    if "joints" not in data or any(k not in limit_table for k in URDF_LIMITS):
        urdf_joints = _urdf_joints(read_text(urdf.resolve(robot), f"the {robot} URDF"), robot)
    joints = names_field(data["joints"], f"the {robot} joints") if "joints" in data else tuple(
        j for j in urdf_joints if j not in fingers
    )
    if not joints:
        raise BadInputError(f"the {robot} has no moving joints")
    if urdf_joints is not None and set(joints) - set(urdf_joints):
        raise BadInputError(f"the {robot} URDF has no moving joints {', '.join(sorted(set(joints) - set(urdf_joints)))}")
    contact = None
    if "contact" in data:
        entry = table_field(data, "contact", {"name", "frame", "offset", "joints"}, f"the {robot}")
        offset = finite_vector(entry.get("offset", [0.0, 0.0, 0.0]), 3, f"the {robot} contact offset")
        if float(np.linalg.norm(offset)) > MAX_CONTACT_LENGTH:
            raise BadInputError(f"the {robot} contact offset must lie within {MAX_CONTACT_LENGTH:g} m of its frame")
        moving = names_field(entry.get("joints", []), f"the {robot} contact joints")
        if set(moving) - set(joints):
            raise BadInputError(f"the {robot} contact joints {', '.join(sorted(set(moving) - set(joints)))} are not its joints")
        contact = RobotContact(name_field(entry.get("name"), "the contact's name"), name_field(entry.get("frame"), "the contact's frame"),
                               _read_only(offset), moving)
    held = held_contacts_of(data.get("held_contacts", []), robot)
    postures = _postures(named_tables_field(data, "postures", robot), len(joints), robot)
    stances = stances_of(named_tables_field(data, "stances", robot), len(held), robot)
    named = postures if postures else stances
    default = data.get("default_posture", next(iter(named), ""))
    if named and default not in named:
        raise BadInputError(f"the {robot} default_posture {default!r} is not one of {', '.join(named)}")
    tool_frames = table_field(data, "tool_frames", {"hand", "flange"}, f"the {robot}")
    frames = data.get("frames", {})
    if not isinstance(frames, Mapping):
        raise BadInputError(f"the {robot} [frames] must be a table of names to URDF frames")
    nominal = table_field(data, "nominal_posture", set(joints), f"the {robot}")
    nominal = {name: number_in_range(value, -2 * np.pi, 2 * np.pi, f"the {robot} nominal_posture {name}", "rad")
               for name, value in nominal.items()}
    limits = _limits(limit_table, joints, urdf_joints, robot)
    _postures_within(postures, joints, limits, robot)
    return RobotDescription(
        name=robot, base=kind, urdf=urdf, meshes=meshes, joints=joints,
        **limits,
        tool_frames={k: name_field(v, f"the {robot} tool frame {k}") for k, v in tool_frames.items()},
        hand_frame=str(hand.get("frame", "")), finger_joints=fingers,
        finger_links=names_field(hand.get("finger_links", []), f"the {robot} finger_links"),
        contact=contact, held_contacts=held, postures=postures, stances=stances, default_posture=default,
        frames={name_field(k, f"the {robot} [frames] key"): name_field(v, f"the {robot} frame {k}") for k, v in frames.items()},
        nominal_posture=nominal, source=source,
    )


def load_robot_description(path: str | Path) -> RobotDescription:
    """The robot described in the TOML, JSON or YAML file ``path`` (module docstring)."""
    path = Path(path).absolute()
    data = read_mapping(path, "the robot description")
    try:
        return description_from_mapping(data, path.parent, path)
    except BadInputError as error:  # the message names the file, whatever key or value it is about
        raise BadInputError(f"the robot description {path}: {error}") from None


BUILTIN_ORDER = ("panda", "fr3", "ur5", "g1")
"""The order the built-in robots are listed in (any other file in the folder comes after them)."""


class BuiltinRobots(Mapping):
    """The built-in descriptions by name, each read from its file on first use."""

    def __init__(self, folder: Path):
        rank = {name: i for i, name in enumerate(BUILTIN_ORDER)}
        self._files = {p.stem: p for p in sorted(folder.glob("*.toml"), key=lambda p: (rank.get(p.stem, len(rank)), p.stem))}
        self._loaded: dict[str, RobotDescription] = {}

    def __getitem__(self, name: str) -> RobotDescription:
        if name not in self._loaded:
            self._loaded[name] = load_robot_description(self._files[name])
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._files)

    def __len__(self) -> int:
        return len(self._files)


ROBOTS: Mapping[str, RobotDescription] = BuiltinRobots(BUILTIN_DIR)
"""The built-in robots by name: ``panda``, ``fr3``, ``ur5`` (fixed-base arms), ``g1`` (standing humanoid)."""
PANDA = ROBOTS["panda"]
"""The default robot: the Panda."""


def robot_description(robot: str | Path | RobotDescription) -> RobotDescription:
    """The description ``robot``: returned as is, a built-in name of :data:`ROBOTS`, or the path
    of a robot file (``.toml``, ``.json``, ``.yaml``)."""
    if isinstance(robot, RobotDescription):
        return robot
    if isinstance(robot, str) and robot in ROBOTS:
        return ROBOTS[robot]
    if isinstance(robot, (str, Path)) and Path(robot).suffix.lower() in ROBOT_FILE_SUFFIXES:
        return load_robot_description(robot)
    raise BadInputError(f"unknown robot {str(robot)!r}; choose from {', '.join(ROBOTS)} or give a .toml robot file")


def model_urdf(robot: RobotDescription, tool: ToolDescription, urdf_path: str | Path | None = None) -> str:
    """The robot's URDF text as the model and the scene load it: unchanged, or, when the tool
    replaces the hand, without the fingers (links and joints) and without the hand link's
    inertial, visual and collision elements (the link stays: its frame is the ``"hand"`` frame)."""
    path = Path(urdf_path) if urdf_path is not None else robot.urdf_path()
    text = read_text(path, f"the {robot.name} URDF")
    _urdf_joints(text, robot.name)  # valid XML, or one line of bad input
    check_link_inertias(text, robot.name)
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
