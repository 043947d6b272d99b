"""The robot interface of the control loop: read the state, send a joint-velocity command, stop.

A backend (``sim.sim_backend``, ``franka_backend``, ``replay_backend``) implements
:class:`RobotInterface`; the loop runner (``controller.runtime.loop``) makes every decision, so a
backend only maps its robot's state and command types.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RobotState:
    """One sample of the robot: time t (s, the robot's clock), the actuated joints' positions q
    (rad), velocities dq (rad/s), the last measured joint torques tau (N m: the torque that acted
    over the period before this sample), the robot's own external-torque estimate tau_ext (N m)
    when it gives one (None otherwise), and a floating base's state ``base`` (13 values: position,
    quaternion x, y, z, w, and twist in the base frame, the dataset's base columns; None for a
    fixed base)."""

    t: float
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    tau_ext: np.ndarray | None = None
    base: np.ndarray | None = None


class RobotInterface:
    """A robot driven at a fixed period by joint-velocity commands (one per actuated joint).

    ``read`` returns the next state (a paced backend blocks until the next period), ``start``
    begins real time once the loop has prepared its controller from the first state, ``write``
    sends the command of that cycle, ``stop`` ends the motion (after the loop brought the
    command to zero). ``finished`` is True when the backend has no more states (a replay).
    A robot that calls its controller (libfranka's callback API) sets ``drives_cycles`` and
    implements ``drive`` instead of ``start``, ``write`` and ``stop``.
    """

    period: float = 1e-3
    finished: bool = False
    drives_cycles: bool = False  # True: the robot calls the loop every period (``drive``)

    def read(self) -> RobotState:
        raise NotImplementedError

    def start(self) -> RobotState | None:
        """Begin real time: from now on a command is due every period. A backend whose state
        moved on while it started returns its newest state (the first cycle's), else None."""
        return None

    def write(self, dq_cmd: np.ndarray) -> None:
        raise NotImplementedError

    def stop(self) -> None:
        """End the motion; the default has nothing to release."""

    def drive(self, cycle) -> None:
        """For a robot that calls its controller every period (``drives_cycles``): run the
        motion, calling ``cycle(state) -> (dq_cmd, over)`` once per period until ``over``, and
        return when the motion has ended; replaces ``start``, ``read``, ``write`` and ``stop``."""
        raise NotImplementedError

    def failed(self, error: BaseException) -> None:
        """The run ended on this error of the backend (the loop can no longer command the
        robot); a robot may name its reflex and recover. The default has nothing to do."""

    def report(self) -> dict:
        """What the backend measured of the connection (command success rate, missed packets,
        reflex) for the run's report; empty by default."""
        return {}

    def force_log(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(force_t, force): the contact force on the robot (world frame, N) when the backend
        measures it (the simulation), else None."""
        return None
