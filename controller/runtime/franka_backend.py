"""The ``franka`` backend: a Franka Research 3 through the official ``pylibfranka`` bindings
(libfranka >= 0.10), in joint-velocity control (``pip install -e '.[franka]'``; imported only
when chosen).

The adapter is thin on purpose: it maps ``RobotState`` (``time``, ``q``, ``dq``, ``tau_J``,
``tau_ext_hat_filtered``) to :class:`RobotState` and a command to ``JointVelocities``, and follows
libfranka's protocol; every decision (filtering, watchdog, braking, impact detection) is the
loop runner's. Before ``start`` no motion runs and ``read`` is ``Robot.read_once``, so the loop
prepares its controller outside real time; ``start`` opens joint-velocity control and reads the
first real-time state; from then on ``readOnce`` blocks until the robot's next 1 kHz cycle, which
paces the loop, and every ``writeOnce`` follows one ``readOnce``. The settings, model check and
statistics shared with the ``panda`` backend: ``libfranka_robot``. Set-up (real-time kernel,
network, ``[libfranka]`` table): ``docs/robot-loop.md``.
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig

from .interface import RobotState
from .libfranka_robot import LibfrankaRobot, state_from_franka

INSTALL_HINT = "pip install -e '.[franka]'"


def import_pylibfranka():
    try:
        import pylibfranka  # optional dependency (the franka extra): imported only when the backend is chosen
    except ImportError:
        raise BadInputError(f"--backend franka needs pylibfranka, which is not installed: {INSTALL_HINT}") from None
    return pylibfranka


def franka_command(pylibfranka, dq_cmd: np.ndarray, finished: bool = False):
    """A ``JointVelocities`` command; ``finished`` ends the motion generator."""
    command = pylibfranka.JointVelocities([float(x) for x in dq_cmd])
    command.motion_finished = finished
    return command


def franka_errors(pylibfranka) -> tuple[type[BaseException], ...]:
    """Every exception class of the bindings. They do not share a base class
    (``ControlException`` is not a ``FrankaException``), so they are caught as this tuple."""
    return tuple(
        value
        for name, value in vars(pylibfranka).items()
        if name.endswith("Exception") and isinstance(value, type) and issubclass(value, BaseException)
    )


class FrankaRobot(LibfrankaRobot):
    """A connected ``pylibfranka.Robot`` (``connect``) in joint-velocity control."""

    ROBOT = "fr3"  # the robot this backend drives (robot_description.ROBOTS)
    BINDINGS_MODULE = "pylibfranka"

    def __init__(self, robot, pylibfranka, settings: RobotConfig | None = None):
        super().__init__(robot, franka_errors(pylibfranka), (pylibfranka.ControlException,), settings)
        self.franka = pylibfranka
        self.control = None

    bindings = staticmethod(import_pylibfranka)

    @staticmethod
    def open(franka, ip: str, config, realtime: bool):
        try:
            return franka.Robot(ip, config)
        except franka.NetworkException as error:
            raise BadInputError(f"no robot answers at {ip}: {error}") from None
        except franka.RealtimeException as error:
            raise BadInputError(
                f"real-time scheduling is not available ({error}); see docs/robot-loop.md or use --realtime ignore"
            ) from None
        except franka_errors(franka) as error:
            raise BadInputError(f"the robot at {ip} refused the connection: {error}") from None

    def read(self) -> RobotState:
        if self.control is None:
            try:
                return state_from_franka(self.robot.read_once())
            except self.errors as error:
                raise BadInputError(f"the robot state cannot be read: {error}") from None
        state, duration = self.control.readOnce()
        self.record(state.control_command_success_rate, duration.to_sec())
        return state_from_franka(state)

    def start(self) -> RobotState:
        self.scheduling.motion_started()
        try:
            self.control = self.robot.start_joint_velocity_control(self.franka.ControllerMode.JointImpedance)
            state, _ = self.control.readOnce()
        except self.errors as error:
            self.scheduling.motion_ended()
            raise BadInputError(f"the robot refused joint-velocity control: {error}") from None
        return state_from_franka(state)

    def write(self, dq_cmd: np.ndarray) -> None:
        self.control.writeOnce(franka_command(self.franka, dq_cmd))

    def stop(self) -> None:
        """Finish the motion (the loop brought the command to zero first)."""
        try:
            if self.control is not None:
                state, _ = self.control.readOnce()
                self.control.writeOnce(franka_command(self.franka, np.zeros(len(state.dq)), finished=True))
                self.control = None
        finally:
            self.scheduling.motion_ended()

    def failed(self, error: BaseException) -> None:
        self.control = None  # libfranka ended the motion
        super().failed(error)
