"""Surfaces, the default wall and what a named impact posture is.

The default wall is the vertical plane x = 0.6 m in front of the robot; its normal points back
towards the robot, n = (-1, 0, 0). A robot's named postures (its description file,
``robot_description``) put the tool tip on that wall with the tool's axis along -n, so the tip is
the first point to touch; they differ in their elbow and wrist arrangement, like the three
configurations of the paper's Fig. 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .validation import BadInputError, finite_vector, number_in_range, unit_normal


MAX_FRICTION = 2.0
"""Largest Coulomb friction coefficient of a surface: rubber on dry rough surfaces stays below 2."""

MAX_SURFACE_DISTANCE = 10.0
"""m: the largest distance of a surface's point from the robot's base (the Panda reaches 0.855 m)."""


@dataclass(frozen=True)
class Surface:
    """A planar rigid surface: a point on it and its unit normal pointing towards the robot."""

    point: np.ndarray
    normal: np.ndarray
    friction: float = 0.1123

    def __post_init__(self):
        point = finite_vector(self.point, 3, "the surface point")
        if math.hypot(*point.tolist()) > MAX_SURFACE_DISTANCE:  # no overflow of a squared entry
            raise BadInputError(
                f"the surface point {point.tolist()} must lie within {MAX_SURFACE_DISTANCE:g} m of the robot's base"
            )
        normal = unit_normal(self.normal)
        number_in_range(self.friction, 0.0, MAX_FRICTION, "the surface friction")
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "normal", normal)

    def signed_distance(self, p: np.ndarray) -> float:
        """Distance of p from the plane, positive on the robot's side."""
        return float(self.normal @ (np.asarray(p) - self.point))


DEFAULT_WALL = Surface(point=np.array([0.6, 0.0, 0.0]), normal=np.array([-1.0, 0.0, 0.0]))


@dataclass(frozen=True)
class ImpactPosture:
    name: str
    q: np.ndarray
    description: str
    surface: Surface = field(default=DEFAULT_WALL)
