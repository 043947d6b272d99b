"""What the two libfranka backends share (``franka``: pylibfranka for the FR3; ``panda``:
panda-python's libfranka 0.9 for the Panda): the robot's settings of the ``[libfranka]`` table
applied on connect, the check of the robot's own dynamic model against ours, the statistics
of the connection and the naming of a reflex.

Load: ``Robot.set_load(m, F_x_Cload, I_load)`` takes the mass, the centre of mass in the flange
frame F and the inertia about the centre of mass in F's axes (3x3, column-major). The declared
tool (``ToolDescription``: m, c and I_c in its own frame T) gives F_x_Cload = X_FT c and
I_load = R_FT I_c R_FT^T, X_FT = (R_FT, p_FT) the tool frame's placement in the flange frame;
each of the three that the ``[libfranka]`` table sets replaces the tool's. The load is what the robot
carries beyond the end effector configured on the robot (the Franka Hand, usually).

Model check: at the state on connect, with M_r the robot's mass matrix (``Model.mass``) and M
ours, the relative difference ||M_r - M||_F / ||M_r||_F above ``max_model_difference`` refuses
the robot (wrong robot, wrong tool or wrong model). Statistics: the smallest
``control_command_success_rate`` of the run and the packets missed, counted from the time each
read covers (``Duration`` of ``readOnce``, one period when no packet was missed).
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig

from .collision_thresholds import CollisionThresholds, fixed_thresholds
from .interface import RobotInterface, RobotState


@dataclass(frozen=True)
class Load:
    """The arguments of ``Robot.set_load``: mass (kg), centre of mass (m, flange frame) and
    inertia about it (kg m^2, 9 numbers column-major, flange axes)."""

    mass: float
    com: list[float]
    inertia: list[float]


def declared_load(model: PandaModel, settings: RobotConfig) -> Load:
    """The load of ``model``'s tool in the flange frame, each entry the ``[libfranka]`` table sets
    taking its place (module docstring)."""
    tool = model.tool
    data = model.model.createData()
    pin.framesForwardKinematics(model.model, data, pin.neutral(model.model))
    flange = data.oMf[model.model.getFrameId(model.description.flange_frame)]
    X = flange.actInv(data.oMf[model.tool_frame_id])
    com = X.act(np.asarray(tool.com, dtype=float))
    inertia = X.rotation @ np.asarray(tool.inertia, dtype=float) @ X.rotation.T
    return Load(
        float(tool.mass) if settings.load_mass is None else float(settings.load_mass),
        com.tolist() if settings.load_com is None else list(settings.load_com),
        inertia.ravel(order="F").tolist() if settings.load_inertia is None else list(settings.load_inertia),
    )


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


def error_names(errors) -> list[str]:
    """The names of the flags set in a libfranka ``Errors`` (e.g. ``joint_reflex``)."""
    return sorted(name for name in dir(errors) if not name.startswith("_") and getattr(errors, name) is True)


def model_difference(mass_matrix, model: PandaModel, q) -> float:
    """||M_r - M(q)||_F / ||M_r||_F for the robot's mass matrix M_r (nv x nv or its nv^2 entries:
    M is symmetric, so the storage order does not matter)."""
    robot_M = np.asarray(mass_matrix, dtype=float).reshape(model.nv, model.nv)
    ours = model.terms(np.asarray(q, dtype=float), np.zeros(model.nv), check_limits=False).M
    return float(np.linalg.norm(robot_M - ours) / np.linalg.norm(robot_M))


def missed_packets(read_duration: float, period: float) -> int:
    """Packets missed before a read that covers ``read_duration`` seconds of the robot's time."""
    return max(0, int(round(read_duration / period)) - 1)


ANSWER_TIMEOUT = 3.0
"""s a robot has to answer a connection (after the child process imported the bindings)."""
IMPORT_TIMEOUT = 60.0
"""s the child process may take to import the bindings (a busy machine)."""
_PROBE = """
import sys
module = __import__(sys.argv[1], fromlist=["Robot"])
print("imported", flush=True)
try:
    module.Robot(sys.argv[2], module.RealtimeConfig.kIgnore)
except Exception:
    pass  # refused, or an error of the protocol: the connection in the process says which
print("answered", flush=True)
"""


def answers_within(module: str, ip: str, timeout: float) -> None:
    """Bad input unless the robot at ``ip`` answers a connection of the bindings ``module``
    within ``timeout`` s (an answer that refuses counts: the connection in this process then
    names the refusal). The child process is killed on return, on a timeout or on a stop signal
    (the wait here is interruptible)."""
    child = subprocess.Popen(
        [sys.executable, "-c", _PROBE, module, ip], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    try:
        if not _prints_within(child, "imported", IMPORT_TIMEOUT):
            raise BadInputError(f"the libfranka bindings {module} did not load within {IMPORT_TIMEOUT:g} s")
        if not _prints_within(child, "answered", timeout):
            raise BadInputError(
                f"the robot at {ip} accepted the connection but did not answer within {timeout:g} s: "
                "is it a Franka robot with FCI active?"
            )
    finally:
        child.kill()
        child.wait()
        child.stdout.close()


def _prints_within(child: subprocess.Popen, expected: str, limit: float) -> bool:
    """Whether the child's next line is ``expected``, printed within ``limit`` s."""
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        ready, _, _ = select.select([child.stdout], [], [], 0.05)
        if ready:
            return child.stdout.readline().strip() == expected
    return False


class ThreadScheduling:
    """The calling thread's scheduling around libfranka. Opening a ``Robot`` raises the calling
    thread to the highest real-time priority (SCHED_FIFO 99, wherever the system allows it, with
    ``RealtimeConfig.kIgnore`` too) and nothing lowers it again: a process that goes on after its
    run (a script that diagnoses its log, a test worker) would keep a real-time thread that takes
    a whole core from every other process whenever it computes. So the thread is given its own
    scheduling back right after the robot is opened (``opened``), libfranka's for each motion
    (``motion_started``) and its own again when the motion ends (``motion_ended``)."""

    def __init__(self):
        self.own: tuple[int, os.sched_param] | None = None
        self.motion: tuple[int, os.sched_param] | None = None

    def opened(self, open_robot):
        """``open_robot()`` (libfranka's constructor), the thread's scheduling kept around it."""
        if not hasattr(os, "sched_getscheduler"):
            return open_robot()
        self.own = (os.sched_getscheduler(0), os.sched_getparam(0))
        robot = open_robot()
        self.motion = (os.sched_getscheduler(0), os.sched_getparam(0))
        self.motion_ended()
        return robot

    def motion_started(self) -> None:
        if self.motion is not None:
            os.sched_setscheduler(0, *self.motion)

    def motion_ended(self) -> None:
        if self.own is not None:
            os.sched_setscheduler(0, *self.own)


class LibfrankaRobot(RobotInterface):
    """A connected libfranka ``Robot``: ``robot`` (the bindings' object), ``errors`` (the
    bindings' exception classes), ``reflex_errors`` (those a motion aborted by a reflex raises)
    and the ``[libfranka]`` settings (None: the defaults). A backend names its robot (``ROBOT``),
    imports its bindings (``bindings``) and opens their ``Robot`` (``open``); ``connect`` is
    the same for both."""

    ROBOT = ""  # the robot the backend drives (robot_description.ROBOTS)

    def __init__(self, robot, errors: tuple[type[BaseException], ...], reflex_errors: tuple, settings: RobotConfig | None):
        self.robot = robot
        self.errors = errors
        self.reflex_errors = reflex_errors
        self.settings = RobotConfig() if settings is None else settings
        self.success_rate = 1.0
        self.missed_packets = 0
        self.reflex: list[str] = []
        self.recovered = False
        self.model_difference: float | None = None
        self.load: Load | None = None
        self.collision: CollisionThresholds | None = None
        self.scheduling = ThreadScheduling()  # ``connect``'s: libfranka's for a motion, the thread's own between

    BINDINGS_MODULE = ""  # the module whose ``Robot(ip, RealtimeConfig.kIgnore)`` the probe opens

    @classmethod
    def connect(
        cls, ip: str, settings: RobotConfig | None = None, realtime: bool = True, model: PandaModel | None = None,
        thresholds: CollisionThresholds | None = None,
    ) -> LibfrankaRobot:
        """The robot at ``ip`` with the ``[libfranka]`` settings, the collision ``thresholds``
        (None: the table's fixed lists) and the load of ``model``'s tool (default: the backend's
        robot with the default tool) applied; bad input when it does not answer or refuses them.
        ``realtime=False`` lets libfranka run without a real-time kernel.

        A peer that accepts the connection and never answers would block libfranka's connect for
        minutes, holding the interpreter's lock (no signal is handled meanwhile): the connection
        is first tried in a child process (``answers_within``), which is killed after
        ``ANSWER_TIMEOUT``."""
        bindings = cls.bindings()
        answers_within(cls.BINDINGS_MODULE, ip, ANSWER_TIMEOUT)
        config = bindings.RealtimeConfig.kEnforce if realtime else bindings.RealtimeConfig.kIgnore
        scheduling = ThreadScheduling()
        connected = cls(scheduling.opened(lambda: cls.open(bindings, ip, config, realtime)), bindings, settings)
        connected.scheduling = scheduling
        connected.configure(ip, RobotModel(cls.ROBOT) if model is None else model, thresholds)
        return connected

    @staticmethod
    def bindings():
        """The backend's libfranka bindings (an optional dependency); bad input when missing."""
        raise NotImplementedError

    @staticmethod
    def open(bindings, ip: str, config, realtime: bool):
        """The bindings' ``Robot`` at ``ip`` with the ``RealtimeConfig`` ``config``; bad input,
        in one line, when it cannot be opened."""
        raise NotImplementedError

    def configure(self, ip: str, model: PandaModel, thresholds: CollisionThresholds | None = None) -> None:
        """Set the collision ``thresholds`` (None: the table's fixed lists), the joint impedance of
        ``settings`` and the load of ``model``'s tool (``declared_load``)."""
        s = self.settings
        load = self.load = declared_load(model, s)
        c = self.collision = fixed_thresholds(s) if thresholds is None else thresholds
        steps = (
            ("collision thresholds", lambda: self.robot.set_collision_behavior(
                c.lower_torque, c.upper_torque, c.lower_force, c.upper_force
            )),
            ("joint impedance", lambda: self.robot.set_joint_impedance(s.joint_impedance)),
            ("load", lambda: self.robot.set_load(load.mass, load.com, load.inertia)),
        )
        for what, step in steps:
            try:
                step()
            except self.errors as error:
                raise BadInputError(f"the robot at {ip} refused the {what}: {error}") from None

    def check_model(self, model: PandaModel) -> float:
        """The model difference (module docstring); bad input above ``max_model_difference``."""
        try:
            state = self.robot.read_once()
            mass = self.robot.load_model().mass(state)
        except self.errors as error:
            raise BadInputError(f"the robot's dynamic model cannot be read: {error}") from None
        difference = model_difference(mass, model, state.q)
        self.model_difference = difference
        limit = self.settings.max_model_difference
        if difference > limit:
            raise BadInputError(
                f"the robot's mass matrix differs from our model's by {100 * difference:.1f} % "
                f"(limit {100 * limit:.1f} %): another robot, tool or model? "
                "Raise [libfranka] max_model_difference to accept it"
            )
        return difference

    def record(self, success_rate: float, read_duration: float) -> None:
        """Count one real-time read."""
        self.success_rate = min(self.success_rate, float(success_rate))
        self.missed_packets += missed_packets(read_duration, self.period)

    def failed(self, error: BaseException) -> None:
        """After a reflex: name it from the robot's errors and, when ``automatic_error_recovery``
        is set, clear the robot's error state. The motion has ended: the thread's scheduling is
        put back."""
        self.scheduling.motion_ended()
        if not isinstance(error, self.reflex_errors):
            return
        try:
            state = self.robot.read_once()
            self.reflex = error_names(state.last_motion_errors) or error_names(state.current_errors)
            if self.settings.automatic_error_recovery:
                self.robot.automatic_error_recovery()
                self.recovered = True
        except self.errors:
            pass  # the connection is gone as well: the run's watchdog reason says why it ended

    def report(self) -> dict:
        return {
            "command_success_rate": self.success_rate,
            "missed_packets": self.missed_packets,
            "reflex": self.reflex,
            "recovered": self.recovered,
            "model_difference": self.model_difference,
            "collision_thresholds": None if self.collision is None else self.collision.to_dict(),
        }
