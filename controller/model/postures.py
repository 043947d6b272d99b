"""The default wall and the named impact postures that face it, for each robot.

The default wall is the vertical plane x = 0.6 m in front of the robot; its normal points back
towards the robot, n = (-1, 0, 0). Each named posture puts the tool tip on that wall with the
hand's axis along -n, so the tip is the first point to touch. The postures differ in their elbow
and wrist arrangement, like the three configurations of the paper's Fig. 2.
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


PANDA_POSTURES: dict[str, ImpactPosture] = {
    p.name: p
    for p in (
        ImpactPosture(
            "elbow_right",
            np.array([1.141378, -0.390243, -0.616843, -1.859688, -1.737836, 2.587417, -0.461]),
            "elbow swung right (q3 < 0), wrist rolled down (q5 < 0); tip at (0.6, 0.2, 0.75)",
        ),
        ImpactPosture(
            "elbow_left",
            np.array([-1.387445, -0.928934, 0.883828, -1.976312, 1.914563, 2.531826, -1.852]),
            "elbow swung left (q3 > 0), wrist rolled up (q5 > 0); tip at (0.6, 0.0, 0.75)",
        ),
        ImpactPosture(
            "elbow_up",
            np.array([0.043817, -0.369231, -0.018765, -2.266834, 0.081754, 3.469656, 0.785]),
            "elbow up in the sagittal plane, wrist neutral (q5 ~ 0); tip at (0.6, 0.0, 0.7)",
        ),
    )
}


FR3_POSTURES = PANDA_POSTURES
"""The FR3's named postures: its kinematic chain is the Panda's (the same Denavit-Hartenberg
parameters in Franka's documentation; the test of the descriptions checks that the two URDFs'
joint placements agree) and each posture lies inside its limits, so the same joint positions
put the tool at the same place with the same hand axis (docs/robots.md)."""

POSTURES = PANDA_POSTURES
"""The postures of the default robot, the Panda (any robot's: ``RobotDescription.posture``,
``choice.RobotChoice.posture``)."""

