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
from numba import njit

from impactqp.controller.model.validation import positive, positive_vector

DQ_MAX, DDQ_MAX, JERK_STEP = range(3)
"""The rows of a filter's ``limits`` (3 x joints): dq_max, ddq_max and s = dddq_max dt."""


@njit(cache=True)
def acceleration_for(change: float, s: float, dt: float) -> float:
    """g^-1(change) of one joint (module docstring): the acceleration whose cycle plus its
    jerk-limited ramp-down (jerk step ``s``) changes the velocity by ``change`` over ``dt``."""
    budget = abs(change) / dt
    m = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * budget / s) - 1.0))
    return np.sign(change) * (budget + 0.5 * s * m * (m + 1.0)) / (m + 1.0)


@njit(cache=True)
def filter_step(target, state, limits, dt) -> None:
    """Kernel of :meth:`CommandFilter.__call__`, joint by joint: a = g^-1(target - dq) clipped
    into the jerk box around the previous acceleration, itself first clipped by the velocity
    interval (module docstring); ``state`` (2 x joints: dq, ddq) advanced in place; a target
    with a non-finite entry is the request to stop (0)."""
    stop = False
    for i in range(target.shape[0]):
        if not np.isfinite(target[i]):
            stop = True
    for i in range(state.shape[1]):
        dq, ddq = state[0, i], state[1, i]
        dq_max, ddq_max, s = limits[DQ_MAX, i], limits[DDQ_MAX, i], limits[JERK_STEP, i]
        lower, upper = max(-ddq_max, ddq - s), min(ddq_max, ddq + s)
        velocity_lower = max(-acceleration_for(dq_max + dq, s, dt), (-dq_max - dq) / dt)
        velocity_upper = min(acceleration_for(dq_max - dq, s, dt), (dq_max - dq) / dt)
        # continuity first: the velocity interval only binds where it meets the jerk box
        # (always, from a consistent start; module docstring)
        lower, upper = min(max(velocity_lower, lower), upper), min(max(velocity_upper, lower), upper)
        goal = 0.0 if stop else target[i]
        a = min(max(acceleration_for(goal - dq, s, dt), lower), upper)
        state[0, i] = dq + a * dt
        state[1, i] = a


class CommandFilter:
    """Rate limiter of joint-velocity commands (module docstring), one call per control period,
    in one compiled call (``filter_step``)."""

    def __init__(self, dt: float, dq_max: np.ndarray, ddq_max: np.ndarray, dddq_max: np.ndarray):
        self.dt = positive(dt, "dt", "s")
        dq_max = positive_vector(dq_max, None, "dq_max")
        joints = len(dq_max)
        ddq_max = positive_vector(ddq_max, joints, "ddq_max")
        self.limits = np.array([dq_max, ddq_max, positive_vector(dddq_max, joints, "dddq_max") * self.dt])
        self.state = np.zeros((2, joints))  # the previous command dq and its acceleration ddq

    @classmethod
    def for_robot(cls, robot, dt: float) -> CommandFilter:
        """The filter of the robot's datasheet limits (``PandaModel``)."""
        return cls(dt, robot.dq_max, robot.ddq_max, robot.dddq_max)

    @property
    def dq_max(self) -> np.ndarray:
        return self.limits[DQ_MAX]

    @property
    def ddq_max(self) -> np.ndarray:
        return self.limits[DDQ_MAX]

    @property
    def jerk_step(self) -> np.ndarray:
        """s = dddq_max dt, per joint."""
        return self.limits[JERK_STEP]

    @property
    def dq(self) -> np.ndarray:
        """The previous command (a view of the filter's state)."""
        return self.state[0]

    @property
    def ddq(self) -> np.ndarray:
        """The previous command's acceleration (a view of the filter's state)."""
        return self.state[1]

    def reset(self, dq, ddq=None) -> None:
        """Start from the command dq (clipped into the velocity limits) and acceleration ddq
        (default 0, clipped into the acceleration limits). A loop resets its filter before real
        time: the kernel is loaded here (a step on copies), not in the first period."""
        self.state[0] = np.clip(np.asarray(dq, dtype=float), -self.dq_max, self.dq_max)
        self.state[1] = 0.0 if ddq is None else np.clip(np.asarray(ddq, float), -self.ddq_max, self.ddq_max)
        filter_step(self.state[0].copy(), self.state.copy(), self.limits, self.dt)

    def velocity_change(self, a: np.ndarray) -> np.ndarray:
        """g(a): the velocity change of a cycle at acceleration a plus the jerk-limited ramp-down."""
        s = self.jerk_step
        magnitude = np.abs(a)
        m = np.floor(magnitude / s)
        return np.sign(a) * self.dt * ((m + 1.0) * magnitude - 0.5 * s * m * (m + 1.0))

    def __call__(self, dq_desired) -> np.ndarray:
        """The next command (a new array) for the requested velocity ``dq_desired`` (a request of
        the wrong size is a request to stop). The request is copied into a new writable array:
        the kernel then sees one type of array, the one ``reset`` loaded it for."""
        target = np.array(dq_desired, dtype=float)
        if target.shape != self.state[0].shape:
            target = np.zeros(self.state.shape[1])
        filter_step(target, self.state, self.limits, self.dt)
        return self.state[0].copy()

    def brake(self) -> np.ndarray:
        """The next command of a stop: the request dq = 0 within every limit."""
        return self(np.zeros(self.state.shape[1]))
