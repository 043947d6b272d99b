"""Joint-velocity command filter: no discontinuity ever reaches the robot.

The Franka Control Interface differentiates consecutive joint-velocity commands and stops the
robot when the commanded velocity, acceleration or jerk leaves the datasheet limits
(``joint_velocity_violation``, ``joint_motion_generator_*_discontinuity``). With the previous
command dq_p and its acceleration a_p = (dq_p - dq_pp) / dt, the next command
dq = dq_p + a dt is sent only with

    |a| <= ddq_max,    |a - a_p| <= dddq_max dt,    |dq_p + g(a)| <= dq_max     (per joint)

where g(a) = dt sum_{k >= 0} max(a - k s, 0) (s = dddq_max dt, odd extension for a < 0) is the
velocity change of this cycle plus the one that ramping a down to zero at the jerk limit adds
afterwards. The last condition keeps the velocity limits recursively feasible: if it held at the
previous cycle, a = a_p - s (a jerk-limited ramp-down) satisfies it now, so the three
conditions never conflict for a filter started at rest inside the limits.

The requested acceleration is the one that reaches the requested velocity without overshoot,
a* = g^-1(dq_des - dq_p), clipped into the intersection of the three intervals above.
g^-1 has a closed form: on [m s, (m+1) s), g(a) / dt = (m+1) a - s m (m+1) / 2.
A non-finite request counts as a request to stop (dq_des = 0); braking is the request 0.
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.validation import positive, positive_vector


class CommandFilter:
    """Rate limiter of joint-velocity commands (module docstring), one call per control period."""

    def __init__(self, dt: float, dq_max: np.ndarray, ddq_max: np.ndarray, dddq_max: np.ndarray):
        self.dt = positive(dt, "dt", "s")
        self.dq_max = positive_vector(dq_max, None, "dq_max").copy()
        joints = len(self.dq_max)
        self.ddq_max = positive_vector(ddq_max, joints, "ddq_max").copy()
        self.jerk_step = positive_vector(dddq_max, joints, "dddq_max") * self.dt
        self.dq = np.zeros(joints)
        self.ddq = np.zeros(joints)

    @classmethod
    def for_robot(cls, robot, dt: float) -> CommandFilter:
        """The filter of the robot's datasheet limits (``PandaModel``)."""
        return cls(dt, robot.dq_max, robot.ddq_max, robot.dddq_max)

    def reset(self, dq, ddq=None) -> None:
        """Start from the command dq (clipped into the velocity limits) and acceleration ddq
        (default 0, clipped into the acceleration limits)."""
        self.dq = np.clip(np.asarray(dq, dtype=float), -self.dq_max, self.dq_max)
        self.ddq = np.zeros_like(self.dq_max) if ddq is None else np.clip(np.asarray(ddq, float), -self.ddq_max, self.ddq_max)

    def velocity_change(self, a: np.ndarray) -> np.ndarray:
        """g(a): the velocity change of a cycle at acceleration a plus the jerk-limited ramp-down."""
        s = self.jerk_step
        magnitude = np.abs(a)
        m = np.floor(magnitude / s)
        return np.sign(a) * self.dt * ((m + 1.0) * magnitude - 0.5 * s * m * (m + 1.0))

    def acceleration_for(self, change: np.ndarray) -> np.ndarray:
        """g^-1(change): the acceleration whose cycle plus ramp-down changes the velocity by ``change``."""
        s = self.jerk_step
        budget = np.abs(change) / self.dt
        m = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * budget / s) - 1.0))
        return np.sign(change) * (budget + 0.5 * s * m * (m + 1.0)) / (m + 1.0)

    def __call__(self, dq_desired) -> np.ndarray:
        """The next command (a new array) for the requested velocity ``dq_desired``."""
        target = np.asarray(dq_desired, dtype=float)
        if target.shape != self.dq_max.shape or not np.all(np.isfinite(target)):
            target = np.zeros(len(self.dq_max))
        dq, ddq = self.dq, self.ddq
        lower = np.maximum(-self.ddq_max, ddq - self.jerk_step)
        upper = np.minimum(self.ddq_max, ddq + self.jerk_step)
        velocity_lower = np.maximum(
            -self.acceleration_for(self.dq_max + dq), (-self.dq_max - dq) / self.dt
        )
        velocity_upper = np.minimum(self.acceleration_for(self.dq_max - dq), (self.dq_max - dq) / self.dt)
        # Continuity first: the velocity interval only binds where it meets the jerk box (always,
        # from a consistent start; see the module docstring).
        lower, upper = np.clip(velocity_lower, lower, upper), np.clip(velocity_upper, lower, upper)
        a = np.clip(self.acceleration_for(target - dq), lower, upper)
        self.dq = dq + a * self.dt
        self.ddq = a
        return self.dq.copy()

    def brake(self) -> np.ndarray:
        """The next command of a stop: the request dq = 0 within every limit."""
        return self(np.zeros(len(self.dq_max)))
