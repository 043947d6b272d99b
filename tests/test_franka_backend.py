"""The franka adapter maps pylibfranka's RobotState and JointVelocities faithfully and follows
libfranka's protocol: the controller is prepared before real-time control starts, and every
writeOnce follows one readOnce."""

import re
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import JOINTS, assert_continuous_within_limits
from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.runtime.franka_backend import (
    FrankaRobot,
    franka_command,
    franka_errors,
    state_from_franka,
)
from impactqp.controller.runtime.libfranka_robot import error_names
from impactqp.controller.runtime.loop import ControlLoop
from impactqp.controller.runtime.session import ImpactSession

pylibfranka = pytest.importorskip("pylibfranka", reason="pylibfranka is not installed: pip install -e '.[franka]'")

READ_ATTRIBUTES = ("time", "q", "dq", "tau_J", "tau_ext_hat_filtered")
STATISTICS_ATTRIBUTES = ("control_command_success_rate", "last_motion_errors", "current_errors")


def franka_like_state(t):
    """An object with RobotState's attribute names (RobotState has no Python constructor)."""
    rng = np.random.default_rng(1)
    values = {name: list(rng.normal(size=JOINTS)) for name in READ_ATTRIBUTES[1:]}
    return SimpleNamespace(time=t, O_F_ext_hat_K=[0.0] * 6, **values), values


def test_the_adapter_reads_only_attributes_that_robotstate_has():
    names = set(dir(pylibfranka.RobotState))
    assert set(READ_ATTRIBUTES) <= names and set(STATISTICS_ATTRIBUTES) <= names
    assert "O_F_ext_hat_K" in names


@pytest.mark.parametrize("t", [0.125, SimpleNamespace(to_sec=lambda: 0.125)])
def test_state_mapping(t):
    raw, values = franka_like_state(t)
    state = state_from_franka(raw)
    assert state.t == 0.125
    assert np.array_equal(state.q, values["q"])
    assert np.array_equal(state.dq, values["dq"])
    assert np.array_equal(state.tau, values["tau_J"])
    assert np.array_equal(state.tau_ext, values["tau_ext_hat_filtered"])


def test_command_mapping_builds_real_joint_velocities():
    dq = np.linspace(-0.3, 0.3, JOINTS)
    command = franka_command(pylibfranka, dq)
    assert isinstance(command, pylibfranka.JointVelocities)
    assert np.allclose(command.dq, dq) and not command.motion_finished
    assert franka_command(pylibfranka, np.zeros(JOINTS), finished=True).motion_finished


def test_a_reflex_is_named_by_the_flags_of_the_real_errors_class():
    names = [n for n in dir(pylibfranka.Errors) if not n.startswith("_")]
    assert "joint_reflex" in names and "cartesian_reflex" in names
    assert error_names(pylibfranka.Errors()) == []
    flags = SimpleNamespace(**{n: n in ("joint_reflex", "tau_j_range_violation") for n in names})
    assert error_names(flags) == ["joint_reflex", "tau_j_range_violation"]


NO_ROBOT_HERE = r"no robot answers at {}|real-time scheduling is not available"
"""The two legitimate errors of connecting where no robot answers on a machine without a
real-time kernel: which one libfranka raises first depends on the machine, not on us, and both
are the user's to fix."""


def test_no_robot_at_the_address_is_bad_input(no_robot_address):
    with pytest.raises(BadInputError, match=NO_ROBOT_HERE.format(re.escape(no_robot_address))):
        FrankaRobot.connect(no_robot_address)


def test_every_exception_of_the_bindings_is_caught():
    # they share no base class: ControlException (a reflex mid-run) is not a FrankaException
    assert not issubclass(pylibfranka.ControlException, pylibfranka.FrankaException)
    exported = {v for n, v in vars(pylibfranka).items() if isinstance(v, type) and issubclass(v, BaseException)}
    assert exported and set(franka_errors(pylibfranka)) == exported


class ProtocolError(AssertionError):
    pass


class FciRobot:
    """Stands in for ``pylibfranka.Robot`` (no robot here) with libfranka's rules: no motion
    before ``start_joint_velocity_control``, ``read_once`` only without one, every ``writeOnce``
    after exactly one ``readOnce``, a ``JointVelocities`` command, the motion over once
    ``motion_finished``. The arm tracks the commanded velocity exactly; time advances 1 ms per
    ``readOnce``. Its method names are checked against the real classes below."""

    def __init__(self, q0, events):
        self.q, self.dq, self.t, self.events = np.array(q0, float), np.zeros(JOINTS), 0.0, events
        self.running = self.finished = self.read_pending = False
        self.commands = []
        self.success_rate, self.skip_every = 1.0, None

    def _state(self):
        t = self.t
        zeros = [0.0] * JOINTS
        return SimpleNamespace(
            time=SimpleNamespace(to_sec=lambda: t), q=list(self.q), dq=list(self.dq),
            tau_J=zeros, tau_ext_hat_filtered=zeros, O_F_ext_hat_K=[0.0] * 6,
            control_command_success_rate=self.success_rate,
        )

    def read_once(self):
        if self.running:
            raise ProtocolError("Robot.read_once during a motion")
        self.events.append("read_once")
        return self._state()

    def start_joint_velocity_control(self, mode):
        if self.running or self.finished:
            raise ProtocolError("a second motion")
        assert mode == pylibfranka.ControllerMode.JointImpedance
        self.events.append("start")
        self.running = True
        return self

    def readOnce(self):
        if not self.running or self.read_pending:
            raise ProtocolError("readOnce without a motion, or twice without a writeOnce")
        self.read_pending = True
        periods = 2 if self.skip_every and len(self.commands) % self.skip_every == self.skip_every - 1 else 1
        self.t += periods * 1e-3
        self.success_rate = min(self.success_rate, 1.0 - 0.01 * (periods - 1))
        return self._state(), SimpleNamespace(to_sec=lambda: periods * 1e-3)

    def writeOnce(self, command):
        if not (self.running and self.read_pending) or not isinstance(command, pylibfranka.JointVelocities):
            raise ProtocolError("writeOnce without its readOnce, or not a JointVelocities")
        self.read_pending = False
        self.commands.append(np.array(command.dq))
        self.dq = np.array(command.dq)
        self.q = self.q + 1e-3 * self.dq
        if command.motion_finished:
            self.events.append("finished")
            self.running, self.finished = False, True


def test_fci_stand_in_uses_only_names_of_the_real_classes():
    for name in (
        "read_once", "start_joint_velocity_control", "set_collision_behavior", "set_joint_impedance", "set_load",
        "load_model", "automatic_error_recovery",
    ):
        assert hasattr(pylibfranka.Robot, name)
    assert hasattr(pylibfranka.Model, "mass") and hasattr(pylibfranka.Duration, "to_sec")
    for name in ("readOnce", "writeOnce"):
        assert hasattr(pylibfranka.ActiveControlBase, name)


class RecordingSession(ImpactSession):
    def __init__(self, config, model, events):
        super().__init__(config, model)
        self.events = events

    def start(self, state):
        self.events.append("prepare controller")
        super().start(state)


def test_the_controller_is_prepared_before_real_time_and_the_protocol_holds():
    model, events = PandaModel(), []
    fci = FciRobot(PANDA.postures["elbow_up"].q, events)
    config = ControllerConfig.approach(PANDA.postures["elbow_up"].surface, 0.15, posture_weight=0.0)
    loop = ControlLoop(
        FrankaRobot(fci, pylibfranka), RecordingSession(config, model, events),
        CommandFilter.for_robot(model, config.dt), deadline=float("inf"),
    )
    result = loop.run(0.1)
    assert events == ["read_once", "prepare controller", "start", "finished"]
    assert result.watchdog_trips == 0 and np.all(np.diff(result.log.t) > 0.0)
    commands = np.array(fci.commands)  # every command sent, the last one finishing the motion
    assert np.max(np.abs(commands[len(commands) // 2])) > 0.01 and np.all(commands[-1] == 0.0)
    assert_continuous_within_limits(commands)


def run_fci(fci, settings=None, duration=0.1):
    model = PandaModel()
    config = ControllerConfig.approach(PANDA.postures["elbow_up"].surface, 0.15, posture_weight=0.0)
    robot = FrankaRobot(fci, pylibfranka, settings)
    loop = ControlLoop(robot, ImpactSession(config, model), CommandFilter.for_robot(model, config.dt), deadline=float("inf"))
    return robot, loop.run(duration)


def test_missed_packets_are_counted_from_the_duration_of_each_read():
    fci = FciRobot(PANDA.postures["elbow_up"].q, [])
    fci.skip_every = 10
    robot, result = run_fci(fci)
    reads = len(fci.commands)  # one readOnce per writeOnce
    skipped = sum(1 for k in range(reads) if k % 10 == 9)
    assert robot.report()["missed_packets"] == skipped > 0
    assert robot.report()["command_success_rate"] == fci.success_rate < 1.0


class ReflexRobot(FciRobot):
    """Aborts the motion with libfranka's ControlException at write ``at``; the robot's state then
    reports a joint reflex until ``automatic_error_recovery``."""

    def __init__(self, q0, at):
        super().__init__(q0, [])
        self.at, self.reflex, self.recoveries = at, False, 0

    def writeOnce(self, command):
        if len(self.commands) == self.at:
            self.running, self.read_pending, self.reflex = False, False, True
            raise pylibfranka.ControlException("libfranka: Move command aborted: motion aborted by reflex! [joint_reflex]")
        super().writeOnce(command)

    def read_once(self):
        state = super().read_once()
        names = [n for n in dir(pylibfranka.Errors) if not n.startswith("_")]
        state.last_motion_errors = SimpleNamespace(**{n: self.reflex and n == "joint_reflex" for n in names})
        state.current_errors = SimpleNamespace(**{n: False for n in names})
        return state

    def automatic_error_recovery(self):
        self.recoveries += 1
        self.reflex = False


@pytest.mark.parametrize("recover", [False, True])
def test_a_reflex_ends_the_run_is_named_and_recovered_only_on_request(recover):
    fci = ReflexRobot(PANDA.postures["elbow_up"].q, at=30)
    robot, result = run_fci(fci, RobotConfig(automatic_error_recovery=recover))
    assert result.watchdog_reason.startswith("robot error: ControlException: ") and "\n" not in result.watchdog_reason
    report = robot.report()
    assert report["reflex"] == ["joint_reflex"]
    assert report["recovered"] == recover and fci.recoveries == int(recover)
