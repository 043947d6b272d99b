"""The contacts a standing robot holds and where they stand: the held contacts and stances of a
robot description (``robot_description``, docs/robots.md).

A held contact is a sole: a polygon in its frame's x-y plane, ``depth`` below the frame, with a
Coulomb friction. A stance places each held contact's frame at (x, y) on its support surface,
a horizontal plane at ``heights[k]`` above the floor (0: the floor; a foot on a step stands
higher), and says where the robot's contact point starts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .description_fields import name_field, table_field
from .validation import BadInputError, finite_vector, number_in_range

MAX_FRICTION = 5.0
MAX_CONTACT_LENGTH = 1.0
"""m: the farthest a robot's own contact point, a sole's corner or its depth lies from its frame."""
MIN_SOLE_AREA = 1e-6
"""m^2: the least area a sole's convex hull covers (a 1 mm square)."""
MAX_SURFACE_HEIGHT = 0.5
"""m: the highest support surface (a step) a stance may put a held contact on."""


@dataclass(frozen=True, eq=False)
class HeldContact:
    """A contact the robot holds while it hits (a humanoid's sole on the ground): the frame it
    is fixed to, the support polygon ``sole`` (k x 2, the frame's x-y plane, m) that lies
    ``depth`` (m) below the frame along its -z axis, the Coulomb ``friction`` on the ground, and
    the ``label`` that reports name it by (default: its name)."""

    name: str
    frame: str
    sole: np.ndarray
    depth: float
    friction: float
    label: str = ""


@dataclass(frozen=True, eq=False)
class Stance:
    """Where a standing robot's held contacts stand (``feet``: x, y of each contact's frame, in
    the description's order; ``heights``: the height of each one's horizontal support surface
    above the floor, m) and where its contact point starts (``hand``)."""

    name: str
    feet: tuple[tuple[float, float], ...]
    hand: tuple[float, float, float]
    heights: tuple[float, ...] = ()

    def height(self, k: int) -> float:
        """The support surface's height under held contact k (0 when the stance gives none)."""
        return self.heights[k] if self.heights else 0.0

    @property
    def coplanar(self) -> bool:
        """Whether every held contact stands on the floor's plane."""
        return not any(self.heights)


def held_contacts_of(entries, robot: str) -> tuple[HeldContact, ...]:
    """The description's ``held_contacts`` (a list of tables)."""
    if not isinstance(entries, list):
        raise BadInputError(f"the {robot} held_contacts must be a list of tables")
    contacts = []
    for entry in entries:
        keys = {"name", "frame", "sole", "depth", "friction"}
        if not isinstance(entry, dict) or not keys <= set(entry) <= keys | {"label"}:
            raise BadInputError(f"each {robot} held contact needs exactly name, frame, sole, depth, friction (and a label)")
        sole = sole_of(entry["sole"])
        if sole.ndim != 2 or sole.shape[1] != 2 or len(sole) < 3 or not np.all(np.abs(sole) <= MAX_CONTACT_LENGTH):
            raise BadInputError(f"the {robot} held contact {entry['name']!r}: sole must be 3 or more (x, y) corners within 1 m")
        if polygon_area(convex_hull(sole)) < MIN_SOLE_AREA:
            raise BadInputError(
                f"the {robot} held contact {entry['name']!r}: the sole's corners enclose no area (their convex hull "
                f"must cover at least {MIN_SOLE_AREA:g} m^2)"
            )
        sole.flags.writeable = False
        contacts.append(HeldContact(
            name_field(entry["name"], "a held contact's name"), name_field(entry["frame"], "a held contact's frame"), sole,
            number_in_range(entry["depth"], 0.0, MAX_CONTACT_LENGTH, "a sole's depth", "m"),
            number_in_range(entry["friction"], 0.0, MAX_FRICTION, "a sole's friction", "", True),
            name_field(entry.get("label", entry["name"]), "a held contact's label"),
        ))
    return tuple(contacts)


def sole_of(corners) -> np.ndarray:
    """A sole's corners as a float array (empty when they are not a list of lists of numbers)."""
    if not isinstance(corners, list) or not all(
        isinstance(c, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in c) for c in corners
    ):
        return np.empty(0)
    try:
        return np.array(corners, dtype=float)
    except ValueError:  # ragged corners
        return np.empty(0)


def polygon_area(polygon: np.ndarray) -> float:
    """The area of the counter-clockwise polygon (k x 2), 0 for fewer than 3 corners (shoelace)."""
    if len(polygon) < 3:
        return 0.0
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def stances_of(table: Mapping, contacts: int, robot: str) -> dict[str, Stance]:
    """The description's ``stances`` (named tables of ``feet``, ``hand`` and optional ``heights``)."""
    stances = {}
    for name in table:
        entry = table_field(table, name, {"feet", "hand", "heights"}, f"the {robot} stance")
        feet = entry.get("feet")
        if not isinstance(feet, list) or len(feet) != contacts:
            raise BadInputError(f"the {robot} stance {name}: feet must give (x, y) for each of the {contacts} held contacts")
        heights = ()
        if "heights" in entry:
            what = f"the {robot} stance {name} heights"
            values = finite_vector(entry["heights"], contacts, what)
            heights = tuple(number_in_range(h, 0.0, MAX_SURFACE_HEIGHT, what, "m") for h in values)
        stances[name] = Stance(
            name,
            tuple(tuple(finite_vector(f, 2, f"the {robot} stance {name} foot").tolist()) for f in feet),
            tuple(finite_vector(entry.get("hand"), 3, f"the {robot} stance {name} hand").tolist()),
            heights,
        )
    return stances


def cross2(a, b) -> float:
    """The z component of the cross product of two planar vectors."""
    return float(a[0] * b[1] - a[1] * b[0])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Monotone-chain convex hull of 2-D points, counter-clockwise."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))

    def half(seq):
        chain = []
        for p in seq:
            while len(chain) >= 2 and cross2(np.subtract(chain[-1], chain[-2]), np.subtract(p, chain[-2])) <= 0:
                chain.pop()
            chain.append(p)
        return chain[:-1]

    return np.array(half(pts) + half(pts[::-1]))
