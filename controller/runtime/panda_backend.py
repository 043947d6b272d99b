"""The ``panda`` backend: a Franka Panda (FER) through libfranka 0.9.2 as ``panda-python``
ships it (``panda_py.libfranka``; ``pip install -e '.[panda]'``; imported only when chosen).

The Panda's robot system supports libfranka below 0.10 only, whose Python bindings offer the
callback API: ``Robot.control_joint_velocity(callback, controller_mode, limit_rate,
cutoff_frequency)`` calls ``callback(state, duration)`` every 1 kHz period and sends the
``JointVelocities`` it returns. ``drive`` runs the loop runner's ``callback_cycle`` (the same
watchdog, command filter and session as the pull loop of the ``franka`` backend) inside that
callback and finishes the motion when the loop says the run is over. libfranka's own rate
limiter and low-pass filter are off (``limit_rate=False``, ``cutoff_frequency`` = 1 kHz, its
"no filter"): the loop's command filter already keeps every command within the velocity,
acceleration and jerk limits, and the log holds the commands the robot received. The bindings
raise every libfranka error as ``RuntimeError``. The settings, model check and statistics
shared with the ``franka`` backend: ``libfranka_robot``.
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig

from .libfranka_robot import LibfrankaRobot, state_from_franka

INSTALL_HINT = "pip install -e '.[panda]'"
NO_FILTER = 1000.0  # Hz: libfranka's kMaxCutoffFrequency, at which its low-pass filter is off
LIBFRANKA_ERRORS = (RuntimeError,)


def import_libfranka():
    try:
        from panda_py import libfranka  # optional: only the panda backend needs it
    except ImportError:
        raise BadInputError(f"--backend panda needs panda-python, which is not installed: {INSTALL_HINT}") from None
    return libfranka


class PandaRobot(LibfrankaRobot):
    """A connected ``panda_py.libfranka.Robot`` (``connect``) in joint-velocity control through
    the callback API."""

    ROBOT = "panda"  # the robot this backend drives (robot_description.ROBOTS)
    BINDINGS_MODULE = "panda_py.libfranka"
    drives_cycles = True

    def __init__(self, robot, libfranka, settings: RobotConfig | None = None):
        super().__init__(robot, LIBFRANKA_ERRORS, LIBFRANKA_ERRORS, settings)
        self.libfranka = libfranka

    bindings = staticmethod(import_libfranka)

    @staticmethod
    def open(libfranka, ip: str, config, realtime: bool):
        try:
            robot = libfranka.Robot(ip, config)
        except LIBFRANKA_ERRORS as error:
            raise BadInputError(f"no robot answers at {ip}: {' '.join(str(error).split())}") from None
        if realtime and not libfranka.has_realtime_kernel():  # libfranka 0.9 would refuse at the motion's start
            raise BadInputError("real-time scheduling is not available (no real-time kernel); see docs/robot-loop.md "
                                "or use --realtime ignore")
        return robot

    def read(self):
        try:
            return state_from_franka(self.robot.read_once())
        except self.errors as error:
            raise BadInputError(f"the robot state cannot be read: {error}") from None

    def drive(self, cycle) -> None:
        libfranka = self.libfranka

        def callback(state, duration):
            self.record(state.control_command_success_rate, duration.to_sec())
            dq_cmd, over = cycle(state_from_franka(state))
            command = libfranka.JointVelocities([float(x) for x in np.asarray(dq_cmd)])
            return libfranka.motion_finished(command) if over else command

        self.scheduling.motion_started()
        try:
            self.robot.control_joint_velocity(callback, libfranka.ControllerMode.kJointImpedance, False, NO_FILTER)
        finally:
            self.scheduling.motion_ended()
