"""The run-up of a standing robot's QP-driven approach (docs/whole-body-qp.md): where the hand
starts so that the QP reaches the asked contact speed at the stance's own posture.

The hand's approach task tracks the asked speed v with the first-order law a = k_v (v* - v)
(``tasks.ContactApproachTask``): from rest its speed is v (1 - e^(-k_v t)) and it has covered
v (t - (1 - e^(-k_v t)) / k_v), so it is within ``tolerance`` of v after
t = ln(1 / tolerance) / k_v, over the distance

    D(v) = v (ln(1 / tolerance) - (1 - tolerance)) / k_v            (:func:`run_up_distance`).

The run-up posture (:func:`run_up_posture`) is the stance's posture with the contact's arm (its
description's ``contact.joints``) moved back along the closed form's approach direction
(``max_speed.approach_direction``: d = J_arm^+ (-n) per unit hand speed, the body at rest) by D,
so that the hand meets the wall with the stance's posture, the one whose closed form is quoted.
The arm stops short of D where one of its joints would come within ``margin`` of a position
limit: the start then keeps the joints inside their limits and the hand may arrive slower.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .max_speed import approach_direction
from .robot import RobotModel
from .validation import BadInputError

TRACKING_TOLERANCE = 0.01
"""The share of the asked speed the hand may still lack at the wall."""
RUN_UP_STEP = 0.002  # m of hand travel per integration step
LIMIT_MARGIN = 0.05  # rad kept from every arm joint's position limits


def run_up_distance(speed: float, velocity_gain: float, tolerance: float = TRACKING_TOLERANCE) -> float:
    """D(v) (module docstring), m."""
    if not (speed >= 0.0 and velocity_gain > 0.0 and 0.0 < tolerance < 1.0):
        raise BadInputError(f"a run-up needs a speed >= 0, a gain > 0 and a tolerance in (0, 1), got {speed}, {velocity_gain}, {tolerance}")
    return speed * (math.log(1.0 / tolerance) - (1.0 - tolerance)) / velocity_gain


def run_up_posture(robot: RobotModel, q: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """The posture q with the hand moved back along the normal by up to ``distance`` m (module
    docstring): steps of RUN_UP_STEP along -d, stopped before an arm joint comes within
    LIMIT_MARGIN of its position limits."""
    joints = slice(robot.base_nq, None)
    lower, upper = robot.q_min + LIMIT_MARGIN, robot.q_max - LIMIT_MARGIN
    steps = int(math.ceil(distance / RUN_UP_STEP))
    q = np.array(q, dtype=float)
    for k in range(steps):
        step = min(RUN_UP_STEP, distance - k * RUN_UP_STEP)
        d = approach_direction(robot, robot.terms(q), normal)
        moved = pin.integrate(robot.model, q, -step * d)
        if np.any(moved[joints] < lower) or np.any(moved[joints] > upper):
            break
        q = moved
    return q
