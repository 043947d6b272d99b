"""Joint velocity limits on the commanded velocity dq_cmd = dq + ddq dt."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle


class VelocityLimit(Constraint):
    """-dq_max <= dq + ddq s <= dq_max for s = dt and s = h, as the box
    (-dq_max - dq)/h <= ddq <= (dq_max - dq)/h, with h >= dt the cycle's horizon.

    The velocity limit is a row of the QP, next to the acceleration and jerk rows, so nothing is
    clipped after the QP. Bounding dq + ddq h (and, by convexity, dq_cmd = dq + ddq dt) keeps
    the limit recursively feasible under the jerk limits (:class:`ControlCycle`, ``horizon``):
    at the next cycle ddq' = (1 - dt/h) ddq is reachable and keeps dq' + ddq' h = dq + ddq h.
    A bound of dq_cmd alone is not: a joint accelerating towards its limit could not brake in
    time, and the command had to be clipped after the QP (breaking ddq = (dq_cmd - dq)/dt and
    the jerk limit). The box is clipped into the reachable accelerations of the cycle: from a
    velocity outside the limits the constraint asks for the strongest allowed deceleration
    instead of making the QP infeasible. With fewer limits than velocities (a floating base),
    they bound the last joints (the actuated ones) and the base is unbounded.
    """

    name = "joint_velocity_limit"
    is_box = True

    def __init__(self, dq_max: np.ndarray):
        self.dq_max = np.asarray(dq_max, dtype=float)
        self.rows = len(self.dq_max)

    def kernel_parameters(self) -> np.ndarray:
        """dq_max (one per limited joint)."""
        return self.dq_max.copy()

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        n = self.dq_max.shape[0]
        if lower.shape[0] == n:
            symmetric_velocity_bounds(terms.dq, self.dq_max, 1.0 / cycle.horizon, lower, upper)
            return
        lower[:-n], upper[:-n] = -np.inf, np.inf
        symmetric_velocity_bounds(terms.dq[-n:], self.dq_max, 1.0 / cycle.horizon, lower[-n:], upper[-n:])


@njit(cache=True)
def symmetric_velocity_bounds(velocity, limit, inv_h, lower, upper):
    """Kernel: (-limit - velocity) / h <= ddq <= (limit - velocity) / h, per row."""
    for i in range(velocity.shape[0]):
        lower[i] = (-limit[i] - velocity[i]) * inv_h
        upper[i] = (limit[i] - velocity[i]) * inv_h
