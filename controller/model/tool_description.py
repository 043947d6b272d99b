"""Tool descriptions: what the robot hits with, where it touches, and what it weighs.

A :class:`ToolDescription` is rigidly fixed to one frame of the robot, ``frame``:

- ``"hand"``: the Franka Hand's frame (``panda_hand``, ``fr3_hand``: the flange turned by -45 deg
  about its axis, on the same origin); z is the hand's axis, pointing out of the flange;
- ``"flange"``: the arm's flange frame (``panda_link8``, ``fr3_link8``).

Every vector of the description (geometry, contact point, centre of mass, inertia axes) is
expressed in that frame. ``replaces_hand`` says whether the tool replaces the Franka Hand that
the robot's URDF carries: when true, the model drops the hand's (and fingers') inertia and the
tool's own mass is all that hangs on the flange; when false, the tool sits on the hand (held by
the closed fingers, say) and its mass adds to the hand's.

The contact geometry is a :class:`Sphere` or a flat :class:`Pad` (a box whose contact face is
the one the unit ``normal`` points out of). The contact point p of the jump models (the point
whose Jacobian J enters W = J M^-1 J^T, eq. (22)) is ``contact_point``; the contact frame has the
tool frame's orientation. The tool's mass m, centre of mass c and rotational inertia I_c about c
are a payload of the link that carries the frame: they enter M, the locked inertia and the CRB
terms (20) exactly as a rigid body welded there.

:func:`tool_description` takes a built-in name (:data:`TOOLS`) or a JSON/TOML file with the keys
of :meth:`ToolDescription.as_dict` (docs/robots.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .files import read_mapping
from .validation import BadInputError, boolean, finite_vector, name_in, number_in_range, rigid_body_moments, unit_normal

FRAMES = ("hand", "flange")
SHAPES = ("sphere", "pad")
MAX_TOOL_LENGTH = 0.5
"""m: the farthest any point of a tool may lie from its frame."""
MAX_TOOL_MASS = 3.0
"""kg: the rated payload of the Panda and of the FR3."""
GEOMETRY_TOLERANCE = 1e-6
"""m: how far a contact point may lie off the contact surface (JSON round trips)."""
INERTIA_TOLERANCE = 1e-9
"""kg m^2: asymmetry, negative principal moments and triangle-inequality excess accepted."""
TOOL_KEYS = {"name", "frame", "replaces_hand", "geometry", "contact_point", "mass", "com", "inertia"}
REQUIRED_TOOL_KEYS = {"frame", "geometry", "contact_point"}


def _point(value, what: str) -> np.ndarray:
    """A 3-vector (m) at most MAX_TOOL_LENGTH from the tool's frame, read-only."""
    p = finite_vector(value, 3, what)
    if math.hypot(*p.tolist()) > MAX_TOOL_LENGTH:
        raise BadInputError(f"{what} {p.tolist()} must lie within {MAX_TOOL_LENGTH:g} m of the tool's frame")
    p.flags.writeable = False
    return p


@dataclass(frozen=True, eq=False)
class Sphere:
    """A sphere of ``radius`` (m) centred at ``centre``."""

    radius: float
    centre: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "radius", number_in_range(self.radius, 0.0, MAX_TOOL_LENGTH, "the sphere radius", "m", True))
        object.__setattr__(self, "centre", _point(self.centre, "the sphere centre"))

    @property
    def bounding_radius(self) -> float:
        """The farthest any point of the geometry lies from its centre."""
        return self.radius

    def surface_distance(self, p: np.ndarray) -> float:
        """|p - centre| - radius: zero on the sphere."""
        return float(np.linalg.norm(p - self.centre)) - self.radius

    def lowest(self, direction: np.ndarray) -> float:
        """min over the sphere's points x of u . x, u = ``direction`` (the support function of
        -u, negated): u . centre - radius |u|."""
        u = np.asarray(direction, dtype=float)
        return float(u @ self.centre) - self.radius * float(np.linalg.norm(u))

    def as_dict(self) -> dict:
        return {"shape": "sphere", "radius": self.radius, "centre": self.centre.tolist()}


@dataclass(frozen=True, eq=False)
class Pad:
    """A flat pad: a box of full lengths ``size`` = (a, b, thickness) centred at ``centre``, whose
    thickness runs along the unit ``normal`` of its contact face (the face at centre + normal
    thickness / 2). Its axes are :attr:`rotation` (the frame's own axes when the normal is z)."""

    size: np.ndarray
    centre: np.ndarray
    normal: np.ndarray

    def __post_init__(self):
        size = finite_vector(self.size, 3, "the pad size")
        for length in size:
            number_in_range(float(length), 0.0, MAX_TOOL_LENGTH, "each pad length", "m", True)
        normal = unit_normal(self.normal, "the pad normal")
        for name, value in (("size", size), ("normal", normal)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        object.__setattr__(self, "centre", _point(self.centre, "the pad centre"))

    @property
    def rotation(self) -> np.ndarray:
        """The pad's axes in the tool frame (columns x, y, normal): the smallest rotation taking
        the frame's z axis onto the normal, R = I + [v]x + [v]x^2 / (1 + c) with v = z x n and
        c = z.n; a normal with c < 0 is reached from -z after a half turn about x, which keeps
        1 + c away from zero."""
        half_turn = np.diag([1.0, -1.0, -1.0])
        start = np.array([0.0, 0.0, 1.0]) if self.normal[2] >= 0.0 else np.array([0.0, 0.0, -1.0])
        v = pin.skew(np.cross(start, self.normal))
        R = np.eye(3) + v + v @ v / (1.0 + float(start @ self.normal))
        return R if self.normal[2] >= 0.0 else R @ half_turn

    @property
    def bounding_radius(self) -> float:
        """The farthest any point of the box lies from its centre (half its diagonal)."""
        return float(np.linalg.norm(self.size)) / 2.0

    def surface_distance(self, p: np.ndarray) -> float:
        """Distance of p from the contact face (zero on it; the face's edges included)."""
        local = self.rotation.T @ (p - self.centre)
        half = self.size / 2.0
        off_plane = local[2] - half[2]
        outside = np.maximum(np.abs(local[:2]) - half[:2], 0.0)
        return math.hypot(off_plane, *outside.tolist())

    def lowest(self, direction: np.ndarray) -> float:
        """min over the box's points x of u . x, u = ``direction``: reached at a corner,
        u . centre - sum_i |(R^T u)_i| size_i / 2 (R = :attr:`rotation`)."""
        u = np.asarray(direction, dtype=float)
        return float(u @ self.centre) - float(np.abs(self.rotation.T @ u) @ self.size) / 2.0

    def as_dict(self) -> dict:
        return {"shape": "pad", "size": self.size.tolist(), "centre": self.centre.tolist(), "normal": self.normal.tolist()}


def _inertia(value, mass: float) -> np.ndarray:
    """A rotational inertia about the centre of mass: symmetric 3x3, principal moments >= 0 that
    satisfy the triangle inequality (a rigid body's), zero for a massless tool, and at most
    m (2 MAX_TOOL_LENGTH)^2 (every point of a tool lies within MAX_TOOL_LENGTH of its frame, so
    within twice that of its centre of mass)."""
    try:
        I = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise BadInputError("the tool inertia must be a 3x3 matrix of numbers") from exc
    if I.shape != (3, 3) or not np.all(np.isfinite(I)):
        raise BadInputError(f"the tool inertia must be a finite 3x3 matrix, got shape {I.shape}")
    if np.abs(I - I.T).max() > INERTIA_TOLERANCE:
        raise BadInputError("the tool inertia must be symmetric")
    moments = np.linalg.eigvalsh((I + I.T) / 2.0)
    if not rigid_body_moments(moments, INERTIA_TOLERANCE):
        raise BadInputError(
            f"the tool inertia's principal moments {moments.tolist()} are not a rigid body's "
            "(each must be >= 0 and at most the sum of the other two)"
        )
    if mass == 0.0 and moments[2] > INERTIA_TOLERANCE:
        raise BadInputError("a massless tool cannot have a rotational inertia")
    largest = mass * (2.0 * MAX_TOOL_LENGTH) ** 2
    if moments[2] > largest + INERTIA_TOLERANCE:
        raise BadInputError(
            f"the tool inertia's largest principal moment {moments[2]:.3g} kg m^2 exceeds what a {mass:g} kg tool "
            f"within {MAX_TOOL_LENGTH:g} m of its frame can have ({largest:.3g} kg m^2: all its mass "
            f"{2 * MAX_TOOL_LENGTH:g} m from its centre of mass)"
        )
    I = (I + I.T) / 2.0
    I.flags.writeable = False
    return I


@dataclass(frozen=True, eq=False)
class ToolDescription:
    """One tool (module docstring): its frame, whether it replaces the Franka Hand, its contact
    geometry and contact point, and its mass, centre of mass and inertia about that centre."""

    name: str
    frame: str
    replaces_hand: bool
    geometry: Sphere | Pad
    contact_point: np.ndarray
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise BadInputError(f"the tool name must be a non-empty string, got {self.name!r}")
        name_in(self.frame, FRAMES, "the tool frame")
        boolean(self.replaces_hand, "replaces_hand")
        if not isinstance(self.geometry, (Sphere, Pad)):
            raise BadInputError("the tool geometry must be a sphere or a pad")
        contact = _point(self.contact_point, "the contact point")
        if abs(self.geometry.surface_distance(contact)) > GEOMETRY_TOLERANCE:
            raise BadInputError(
                f"the contact point {contact.tolist()} must lie on the contact surface of the "
                f"{self.geometry.as_dict()['shape']} (it is {self.geometry.surface_distance(contact):.3g} m off)"
            )
        mass = number_in_range(self.mass, 0.0, MAX_TOOL_MASS, "the tool mass", "kg")
        object.__setattr__(self, "contact_point", contact)
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "com", _point(self.com, "the tool's centre of mass"))
        object.__setattr__(self, "inertia", _inertia(self.inertia, mass))

    @property
    def spatial_inertia(self) -> pin.Inertia:
        """The tool as a Pinocchio rigid-body inertia in its frame (m, c, I_c)."""
        return pin.Inertia(self.mass, self.com.copy(), self.inertia.copy())

    def as_dict(self) -> dict:
        """The description as the JSON/TOML keys :func:`tool_from_dict` reads back."""
        return {
            "name": self.name,
            "frame": self.frame,
            "replaces_hand": self.replaces_hand,
            "geometry": self.geometry.as_dict(),
            "contact_point": self.contact_point.tolist(),
            "mass": self.mass,
            "com": self.com.tolist(),
            "inertia": self.inertia.tolist(),
        }


def _geometry(value) -> Sphere | Pad:
    if not isinstance(value, dict):
        raise BadInputError("the tool geometry must be an object with a 'shape'")
    shape = name_in(value.get("shape"), SHAPES, "the tool geometry's shape")
    keys = {"sphere": {"shape", "radius", "centre"}, "pad": {"shape", "size", "centre", "normal"}}[shape]
    if set(value) != keys:
        raise BadInputError(f"a {shape} geometry has exactly the keys {sorted(keys)}, got {sorted(value)}")
    if shape == "sphere":
        return Sphere(value["radius"], value["centre"])
    return Pad(value["size"], value["centre"], value["normal"])


def tool_from_dict(data: dict, default_name: str = "tool") -> ToolDescription:
    """The tool described by ``data`` (the keys of :meth:`ToolDescription.as_dict`; ``name``,
    ``replaces_hand`` (false), ``mass`` (0), ``com`` and ``inertia`` (zero) are optional)."""
    if not isinstance(data, dict):
        raise BadInputError("a tool description must be an object")
    unknown, missing = set(data) - TOOL_KEYS, REQUIRED_TOOL_KEYS - set(data)
    if unknown or missing:
        raise BadInputError(
            f"tool description: unknown keys {sorted(unknown)}, missing keys {sorted(missing)}; "
            f"the keys are {sorted(TOOL_KEYS)}"
        )
    mass = data.get("mass", 0.0)
    if isinstance(mass, (int, float)) and not isinstance(mass, bool) and mass > 0.0 and not {"com", "inertia"} <= set(data):
        raise BadInputError("a tool with a mass must give its centre of mass 'com' and its 'inertia'")
    return ToolDescription(
        name=data.get("name", default_name),
        frame=data["frame"],
        replaces_hand=data.get("replaces_hand", False),
        geometry=_geometry(data["geometry"]),
        contact_point=data["contact_point"],
        mass=mass,
        com=data.get("com", (0.0, 0.0, 0.0)),
        inertia=data.get("inertia", np.zeros((3, 3))),
    )


def read_tool_file(path: Path) -> ToolDescription:
    """The tool described in the JSON (``.json``) or TOML (``.toml``) file ``path``."""
    path = Path(path)
    data = read_mapping(path, "the tool file")
    try:
        return tool_from_dict(data, default_name=path.stem)
    except BadInputError as exc:
        raise BadInputError(f"the tool file {path}: {exc}") from None


def _box_inertia(mass: float, size) -> np.ndarray:
    """Rotational inertia of a solid box of full lengths ``size`` about its centre."""
    a2, b2, c2 = np.square(size)
    return mass / 12.0 * np.diag([b2 + c2, a2 + c2, a2 + b2])


def _franka_hand_inertia() -> pin.Inertia:
    """The Franka Hand with closed fingers, in the hand frame: franka_description's inertials of
    the hand (0.73 kg) and of each finger (0.015 kg, centre at the finger joint, 0.0584 m up the
    hand's axis; closed fingers sit on the axis), summed as rigid bodies (docs/robots.md)."""
    hand = pin.Inertia(0.73, np.array([-0.01, 0.0, 0.03]), np.diag([0.001, 0.0025, 0.0017]))
    finger = pin.Inertia(0.015, np.zeros(3), np.diag([2.375e-6, 2.375e-6, 7.5e-7]))
    at_joint = pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.0584]))
    return hand + at_joint.act(finger) + at_joint.act(finger)


_HAND = _franka_hand_inertia()
# The closed fingertips (franka_description's rubber-tip boxes: 17.5 x 15.2 x 18.5 mm centred
# 7.58 mm off the axis and 45.25 mm up each finger) form one 17.5 x 30.4 x 18.5 mm pad whose
# face lies 0.0584 + 0.04525 + 0.00925 = 0.1129 m up the hand's axis.
_FINGERTIPS = Pad((0.0175, 0.0304, 0.0185), (0.0, 0.0, 0.0584 + 0.04525), (0.0, 0.0, 1.0))
_PAD_SIZE, _PAD_MASS = (0.08, 0.08, 0.01), 0.25

TOOLS: dict[str, ToolDescription] = {
    tool.name: tool
    for tool in (
        ToolDescription(
            name="impact_tip",
            frame="hand",
            replaces_hand=False,
            geometry=Sphere(0.02, (0.0, 0.0, 0.12)),
            contact_point=(0.0, 0.0, 0.14),
        ),
        ToolDescription(
            name="franka_hand",
            frame="hand",
            replaces_hand=True,
            geometry=_FINGERTIPS,
            contact_point=(0.0, 0.0, 0.0584 + 0.04525 + 0.00925),
            mass=_HAND.mass,
            com=_HAND.lever,
            inertia=_HAND.inertia,
        ),
        ToolDescription(
            name="pad",
            frame="flange",
            replaces_hand=True,
            geometry=Pad(_PAD_SIZE, (0.0, 0.0, 0.045), (0.0, 0.0, 1.0)),
            contact_point=(0.0, 0.0, 0.05),
            mass=_PAD_MASS,
            com=(0.0, 0.0, 0.045),
            inertia=_box_inertia(_PAD_MASS, _PAD_SIZE),
        ),
    )
}
"""Built-in tools: ``impact_tip``, the project's massless 2 cm sphere held 0.12 m up the hand's
axis (contact at its far pole, 0.14 m); ``franka_hand``, the Franka Hand itself with closed
fingers (contact at the fingertips' face); ``pad``, an example 80 x 80 x 10 mm, 0.25 kg solid
pad on the bare flange (contact at the centre of its face)."""


def tool_description(tool: str | Path | ToolDescription) -> ToolDescription:
    """The tool ``tool``: a description (returned as is), a built-in name or a .json/.toml file."""
    if isinstance(tool, ToolDescription):
        return tool
    if isinstance(tool, str) and tool in TOOLS:
        return TOOLS[tool]
    if isinstance(tool, (str, Path)) and Path(tool).suffix.lower() in (".json", ".toml"):
        return read_tool_file(Path(tool))
    raise BadInputError(f"unknown tool {str(tool)!r}: give one of {', '.join(TOOLS)} or a .json/.toml tool file")
