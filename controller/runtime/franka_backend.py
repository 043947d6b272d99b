"""The ``franka`` backend: a Franka Panda through the official ``pylibfranka`` bindings, in
joint-velocity control (``pip install -e '.[franka]'``; imported only when chosen).

The adapter is thin on purpose: it maps ``RobotState`` (``time``, ``q``, ``dq``, ``tau_J``,
``tau_ext_hat_filtered``) to :class:`RobotState` and a command to ``JointVelocities``, and follows
libfranka's protocol; every decision (filtering, watchdog, braking, impact detection) is the
loop runner's. Before ``start`` no motion runs and ``read`` is ``Robot.read_once``, so the loop
prepares its controller outside real time; ``start`` opens joint-velocity control and reads the
first real-time state; from then on ``readOnce`` blocks until the robot's next 1 kHz cycle, which
paces the loop, and every ``writeOnce`` follows one ``readOnce``. Set-up (real-time kernel,
network, collision thresholds): ``docs/robot-loop.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.robot import NQ
from impactqp.controller.model.validation import BadInputError

from .interface import RobotInterface, RobotState

INSTALL_HINT = "pip install -e '.[franka]'"


@dataclass(frozen=True)
class CollisionThresholds:
    """Thresholds of the robot's own collision reflex (``Robot.set_collision_behavior``):
    torques per joint (N m) and Cartesian force/torque (N, N m). An impact on purpose trips the
    reflex at the factory values; these defaults (``docs/robot-loop.md``) sit above the
    impulsive torques the impact-aware constraints allow (tau_max = 87/12 N m)."""

    lower_torque: tuple[float, ...] = (100.0,) * 4 + (20.0,) * 3
    upper_torque: tuple[float, ...] = (100.0,) * 4 + (20.0,) * 3
    lower_force: tuple[float, ...] = (100.0,) * 3 + (30.0,) * 3
    upper_force: tuple[float, ...] = (100.0,) * 3 + (30.0,) * 3


def import_pylibfranka():
    try:
        import pylibfranka  # optional dependency (the franka extra): imported only when the backend is chosen
    except ImportError:
        raise BadInputError(f"--backend franka needs pylibfranka, which is not installed: {INSTALL_HINT}") from None
    return pylibfranka


def state_from_franka(state) -> RobotState:
    """Our :class:`RobotState` from a ``pylibfranka.RobotState`` (or anything with its names)."""
    t = state.time
    return RobotState(
        float(t.to_sec()) if hasattr(t, "to_sec") else float(t),
        np.array(state.q, dtype=float),
        np.array(state.dq, dtype=float),
        np.array(state.tau_J, dtype=float),
        np.array(state.tau_ext_hat_filtered, dtype=float),
    )


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


class FrankaRobot(RobotInterface):
    """A connected ``pylibfranka.Robot`` (``connect``) in joint-velocity control."""

    def __init__(self, robot, pylibfranka):
        self.franka = pylibfranka
        self.robot = robot
        self.errors = franka_errors(pylibfranka)
        self.control = None

    @classmethod
    def connect(
        cls, ip: str, collision: CollisionThresholds = CollisionThresholds(), realtime: bool = True
    ) -> FrankaRobot:
        """The Panda at ``ip`` with the ``collision`` thresholds; bad input when it does not answer."""
        franka = import_pylibfranka()
        config = franka.RealtimeConfig.kEnforce if realtime else franka.RealtimeConfig.kIgnore
        try:
            robot = franka.Robot(ip, config)
        except franka.NetworkException as error:
            raise BadInputError(f"no robot answers at {ip}: {error}") from None
        except franka.RealtimeException as error:
            raise BadInputError(f"real-time scheduling is not available ({error}); see docs/robot-loop.md") from None
        except franka_errors(franka) as error:
            raise BadInputError(f"the robot at {ip} refused the connection: {error}") from None
        try:
            robot.set_collision_behavior(
                list(collision.lower_torque), list(collision.upper_torque),
                list(collision.lower_force), list(collision.upper_force),
            )
        except franka_errors(franka) as error:
            raise BadInputError(f"the robot at {ip} refused the collision thresholds: {error}") from None
        return cls(robot, franka)

    def read(self) -> RobotState:
        if self.control is None:
            try:
                return state_from_franka(self.robot.read_once())
            except self.errors as error:
                raise BadInputError(f"the robot state cannot be read: {error}") from None
        state, _ = self.control.readOnce()
        return state_from_franka(state)

    def start(self) -> RobotState:
        try:
            self.control = self.robot.start_joint_velocity_control(self.franka.ControllerMode.JointImpedance)
            state, _ = self.control.readOnce()
        except self.errors as error:
            raise BadInputError(f"the robot refused joint-velocity control: {error}") from None
        return state_from_franka(state)

    def write(self, dq_cmd: np.ndarray) -> None:
        self.control.writeOnce(franka_command(self.franka, dq_cmd))

    def stop(self) -> None:
        """Finish the motion (the loop brought the command to zero first)."""
        if self.control is not None:
            self.control.readOnce()
            self.control.writeOnce(franka_command(self.franka, np.zeros(NQ), finished=True))
            self.control = None
