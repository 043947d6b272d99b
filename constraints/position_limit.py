"""Joint position limits with a braking horizon."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle
from impactqp.controller.model.validation import number_in_range


class PositionLimit(Constraint):
    """Keep every joint able to stop before its position limit (braking horizon).

    With a = braking_fraction ddq_max the braking deceleration, d = q_max - margin - q the
    distance to the upper limit, and the commanded motion of one cycle
    q' = q + dt (dq + dq') / 2, dq' = dq + ddq dt, the joint can still stop within the limit
    after the cycle if dq'^2 / (2 a) + a dt^2 / 8 <= d' with d' = d - dt (dq + dq') / 2
    (a dt^2 / 8 bounds the extra travel of the last, partial braking cycle). Solved for dq':

        dq + ddq dt <= sqrt((a dt / 2)^2 + 2 a d_e) - a dt / 2,
        d_e = max(d - dt dq / 2 - a dt^2 / 8, 0)

    an upper bound on ddq (symmetrically a lower bound at the lower limit). It also keeps the
    next commanded position inside the limit (d' >= 0). The bounds are then clipped into the
    reachable accelerations of the cycle (acceleration and jerk limits), so position, velocity
    and acceleration limits stay mutually feasible near the boundary: a joint that is too fast
    brakes as hard as it may. braking_fraction < 1 leaves room for the jerk-limited onset of the
    deceleration and for the other constraints.

    With fewer limits than velocities (a floating base), the limits are those of the last
    joints (the actuated ones; the base's coordinates come first) and the base is unbounded.
    """

    name = "joint_position_limit"
    is_box = True

    def __init__(self, q_min, q_max, ddq_max, braking_fraction: float = 0.5, margin: float = 0.0):
        braking_fraction = number_in_range(braking_fraction, 0.0, 1.0, "braking_fraction", low_open=True)
        margin = number_in_range(margin, 0.0, math.inf, "margin", "rad")
        # Row 0 looks at the upper limits, row 1 at the lower ones (sign -1 mirrors them).
        self._sign = np.array([[1.0], [-1.0]])
        self._limits = np.vstack([np.asarray(q_max, float) - margin, np.asarray(q_min, float) + margin])
        self.rows = self._limits.shape[1]
        self._braking = braking_fraction * np.asarray(ddq_max, dtype=float)
        self._dt = None

    def _constants(self, dt: float) -> None:
        """The terms that depend only on dt: a dt / 2, (a dt / 2)^2 and 2 a (rows of
        ``_braking_terms``) and the signed limits less the last cycle's travel a dt^2 / 8."""
        self._dt = dt
        half_step = (0.5 * dt) * self._braking
        self._braking_terms = np.vstack([half_step, half_step * half_step, 2.0 * self._braking])
        self._signed_limits = self._sign * self._limits - (0.125 * dt * dt) * self._braking

    def kernel_parameters(self, dt: float) -> np.ndarray:
        """The signed limits less a dt^2 / 8 (2 rows), then a dt / 2, (a dt / 2)^2 and 2 a (3
        rows), row-major, at the period dt."""
        if dt != self._dt:
            self._constants(dt)
        return np.concatenate([self._signed_limits.ravel(), self._braking_terms.ravel()])

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        dt = cycle.dt
        if dt != self._dt:
            self._constants(dt)
        n = self._limits.shape[1]
        if lower.shape[0] == n:
            braking_bounds(terms.q, terms.dq, self._signed_limits, self._braking_terms, dt, lower, upper)
            return
        lower[:-n], upper[:-n] = -np.inf, np.inf
        braking_bounds(terms.q[-n:], terms.dq[-n:], self._signed_limits, self._braking_terms, dt, lower[-n:], upper[-n:])


@njit(cache=True)
def braking_bounds(q, dq, signed_limits, braking_terms, dt, lower, upper):
    """Kernel of ``PositionLimit``: with p = q + dq dt / 2, d_up = max(L_up - p, 0) and
    d_low = max(L_low + p, 0) (L the signed limits less a dt^2 / 8), the commanded velocity
    dq + ddq dt stays within +-(sqrt((a dt / 2)^2 + 2 a d) - a dt / 2); ``braking_terms`` rows
    are a dt / 2, (a dt / 2)^2 and 2 a."""
    inv_dt = 1.0 / dt
    for j in range(q.shape[0]):
        half_step, half_step_squared, twice_braking = braking_terms[0, j], braking_terms[1, j], braking_terms[2, j]
        p = q[j] + 0.5 * dt * dq[j]
        up = max(signed_limits[0, j] - p, 0.0)
        low = max(signed_limits[1, j] + p, 0.0)
        upper[j] = (math.sqrt(half_step_squared + twice_braking * up) - half_step - dq[j]) * inv_dt
        lower[j] = -(math.sqrt(half_step_squared + twice_braking * low) - half_step + dq[j]) * inv_dt
