"""Surface-offset task: after an impact, bring the contact point to a set distance from the surface."""

from __future__ import annotations

import math

import numpy as np

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import finite_vector, task_gain, number_in_range, unit_normal

from .task import OrientationHold, Task, rotation_error

MAX_OFFSET = 0.5
"""Largest |offset| (m): a retract or a hold depth beyond half a metre leaves the contact task."""


class SurfaceOffsetTask(Task):
    """Move the contact point along the normal n to the signed distance ``offset`` from the
    surface (through ``surface_point``), at most at ``max_speed``, holding the tangential
    position and the orientation of ``reset``.

    With p0 and R0 the contact point and rotation at ``reset`` (the impact), the target is
    p* = p0 - (n.(p0 - s) - offset) n: ``offset`` > 0 retracts (the paper's experiments pull back
    along the contact normal), ``offset`` <= 0 holds the contact at depth -offset. The desired
    frame acceleration is

        v* = sat(k_p (p* - p), max_speed),   a_lin* = k_v (v* - v)
        a_ang* = k_R log(R0 R^T) - d_R w

    and the rows are J6 ddq = a* - dJ6 dq (world axes; 3 position rows weighted
    ``position_weight``, 3 orientation rows weighted ``orientation.weight``: ``OrientationHold``).
    """

    name = "surface_offset"
    rows = 6

    def __init__(
        self,
        normal,
        surface_point,
        offset: float,
        max_speed: float = 0.1,
        position_gain: float = 20.0,
        velocity_gain: float = 40.0,
        position_weight: float = 1.0,
        orientation: OrientationHold = OrientationHold(),
    ):
        self.normal = unit_normal(normal)
        self.surface_point = finite_vector(surface_point, 3, "surface_point")
        self.offset = number_in_range(offset, -MAX_OFFSET, MAX_OFFSET, "offset", "m")
        self.max_speed = task_gain(max_speed, "max_speed")
        self.position_gain = task_gain(position_gain, "position_gain")
        self.velocity_gain = task_gain(velocity_gain, "velocity_gain")
        if not isinstance(orientation, OrientationHold):
            raise TypeError("orientation must be an OrientationHold")
        self.orientation_stiffness = float(orientation.stiffness)
        self.orientation_damping = orientation.damping_gain()
        self.weight = np.repeat([task_gain(position_weight, "position_weight"), float(orientation.weight)], 3)
        self.target_position: np.ndarray | None = None
        self.target_rotation: np.ndarray | None = None

    def reset(self, terms: ModelTerms) -> None:
        p0 = terms.contact_point
        depth = float(self.normal @ (p0 - self.surface_point)) - self.offset
        self.target_position = p0 - depth * self.normal
        self.target_rotation = terms.contact_rotation.copy()

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        A[:] = terms.J6
        twist = terms.J6 @ terms.dq
        velocity = self.position_gain * (self.target_position - terms.contact_point)
        speed = math.sqrt(velocity @ velocity)
        if speed > self.max_speed:
            velocity *= self.max_speed / speed
        b[:3] = self.velocity_gain * (velocity - twist[:3]) - terms.dJ6_dq[:3]
        b[3:] = (
            self.orientation_stiffness * rotation_error(self.target_rotation, terms.contact_rotation)
            - self.orientation_damping * twist[3:]
            - terms.dJ6_dq[3:]
        )
