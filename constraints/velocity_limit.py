"""Joint velocity limits on the commanded velocity dq_cmd = dq + ddq dt."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.robot import ModelTerms

from .constraint import Constraint, ConstraintRows, ControlCycle


class VelocityLimit(Constraint):
    """-dq_max <= dq + ddq dt <= dq_max, as the box (-dq_max - dq)/dt <= ddq <= (dq_max - dq)/dt.

    The box is clipped into the reachable accelerations of the cycle: from a velocity outside
    the limits the constraint asks for the strongest allowed deceleration instead of making the
    QP infeasible.
    """

    name = "joint_velocity_limit"
    rows = 7
    is_box = True

    def __init__(self, dq_max: np.ndarray):
        self.dq_max = np.asarray(dq_max, dtype=float)

    def compute(self, terms: ModelTerms, cycle: ControlCycle) -> ConstraintRows:
        inv_dt = 1.0 / cycle.dt
        lower = (-self.dq_max - terms.dq) * inv_dt
        upper = (self.dq_max - terms.dq) * inv_dt
        return ConstraintRows(None, *cycle.clip_to_reachable(lower, upper))
