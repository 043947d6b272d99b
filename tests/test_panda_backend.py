"""The panda adapter drives the same loop (watchdog, command filter, session) inside libfranka
0.9's callback API, with panda_py.libfranka's real command classes; the names it uses exist on
the installed package. No server of the 0.9 protocol exists, so the robot is a stand-in that
follows libfranka's callback rules (docs/robot-loop.md)."""

import re
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import ACCELERATION_LIMIT, JERK_LIMIT, VELOCITY_LIMIT, PandaModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig
from impactqp.scenarios.cli import main
from impactqp.controller.runtime.loop import ControlLoop
from impactqp.controller.runtime.panda_backend import PandaRobot
from impactqp.controller.runtime.session import ImpactSession

libfranka = pytest.importorskip("panda_py.libfranka", reason="panda-python is not installed: pip install -e '.[panda]'")

STATE_ATTRIBUTES = (
    "time", "q", "dq", "tau_J", "tau_ext_hat_filtered", "control_command_success_rate", "last_motion_errors",
    "current_errors",
)
ROBOT_METHODS = (
    "read_once", "control_joint_velocity", "set_collision_behavior", "set_joint_impedance", "set_load", "load_model",
    "automatic_error_recovery",
)
ERROR_NAMES = [n for n in dir(libfranka.Errors) if not n.startswith("_")]


def test_the_adapter_uses_only_names_of_the_installed_bindings():
    assert set(STATE_ATTRIBUTES) <= set(dir(libfranka.RobotState))
    assert all(hasattr(libfranka.Robot, name) for name in ROBOT_METHODS)
    signature = libfranka.Robot.control_joint_velocity.__doc__
    for parameter in ("motion_generator_callback", "controller_mode", "limit_rate", "cutoff_frequency"):
        assert parameter in signature
    assert hasattr(libfranka.Model, "mass") and hasattr(libfranka.Duration, "to_sec")
    assert hasattr(libfranka, "has_realtime_kernel") and libfranka.ControllerMode.kJointImpedance is not None
    assert "joint_reflex" in ERROR_NAMES
    finished = libfranka.motion_finished(libfranka.JointVelocities([0.0] * JOINTS))
    assert finished.motion_finished and not libfranka.JointVelocities([0.0] * JOINTS).motion_finished


def test_no_robot_at_the_address_is_bad_input_in_one_line(capsys, no_robot_address):
    with pytest.raises(BadInputError, match=f"no robot answers at {re.escape(no_robot_address)}") as error:
        PandaRobot.connect(no_robot_address, realtime=False)
    assert "\n" not in str(error.value)
    assert main(["run", "--backend", "panda", "--robot-ip", no_robot_address, "--realtime", "ignore"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"no robot answers at {no_robot_address}" in err


class CallbackProtocolError(AssertionError):
    pass


class CallbackRobot:
    """Stands in for ``panda_py.libfranka.Robot`` with libfranka's callback rules: ``read_once``
    outside a motion only; ``control_joint_velocity`` calls back once per 1 ms period with the
    state and the ``Duration`` since the previous call (0 at the first), needs a real
    ``JointVelocities`` back and ends after the one marked ``motion_finished``. The arm tracks the
    command exactly. A ``fault`` at call ``at``: ``"nan"`` (a non-finite state) or ``"reflex"``
    (the motion aborts, the state then reports a joint reflex until recovered)."""

    def __init__(self, q0, fault=None, at=None):
        self.q, self.dq, self.t = np.array(q0, float), np.zeros(JOINTS), 0.0
        self.fault, self.at = fault, at
        self.running = self.reflex = False
        self.commands, self.calls, self.motions, self.recoveries = [], [], 0, 0

    def _state(self, nan=False):
        errors = {n: self.reflex and n == "joint_reflex" for n in ERROR_NAMES}
        q = np.full(JOINTS, np.nan) if nan else self.q
        t = self.t
        return SimpleNamespace(
            time=SimpleNamespace(to_sec=lambda: t), q=list(q), dq=list(self.dq), tau_J=[0.0] * JOINTS,
            tau_ext_hat_filtered=[0.0] * JOINTS, control_command_success_rate=1.0,
            last_motion_errors=SimpleNamespace(**errors), current_errors=SimpleNamespace(**{n: False for n in ERROR_NAMES}),
        )

    def read_once(self):
        if self.running:
            raise CallbackProtocolError("read_once during a motion")
        return self._state()

    def automatic_error_recovery(self):
        self.recoveries += 1
        self.reflex = False

    def control_joint_velocity(self, callback, controller_mode, limit_rate, cutoff_frequency):
        assert controller_mode == libfranka.ControllerMode.kJointImpedance and limit_rate is False
        self.running, self.motions = True, self.motions + 1
        duration = libfranka.Duration(0)
        while True:
            self.t += 1e-3
            if self.fault == "reflex" and len(self.commands) == self.at:
                self.running, self.reflex = False, True
                raise RuntimeError("libfranka: Move command aborted: motion aborted by reflex! [joint_reflex]")
            command = callback(self._state(nan=self.fault == "nan" and len(self.commands) == self.at), duration)
            if not isinstance(command, libfranka.JointVelocities):
                raise CallbackProtocolError("the callback must return JointVelocities")
            self.commands.append(np.array(command.dq))
            self.dq = np.array(command.dq)
            self.q = self.q + 1e-3 * self.dq
            duration = libfranka.Duration(1)
            if command.motion_finished:
                self.running = False
                return


def run_panda(robot, settings=None, duration=0.2):
    model = PandaModel()
    config = ControllerConfig.approach(PANDA.postures["elbow_up"].surface, 0.15, posture_weight=0.0)
    panda = PandaRobot(robot, libfranka, settings)
    loop = ControlLoop(panda, ImpactSession(config, model), CommandFilter.for_robot(model, config.dt), deadline=float("inf"))
    return panda, loop.run(duration)


def assert_within_limits(commands):
    dq = np.vstack([np.zeros((2, JOINTS)), commands])
    ddq = np.diff(dq, axis=0) / 1e-3
    jerk = np.diff(ddq, axis=0) / 1e-3
    assert np.all(np.abs(dq) <= VELOCITY_LIMIT * (1 + 1e-9))
    assert np.all(np.abs(ddq) <= ACCELERATION_LIMIT * (1 + 1e-9))
    assert np.all(np.abs(jerk) <= JERK_LIMIT * (1 + 1e-9))


def test_the_session_runs_inside_the_callback_and_finishes_the_motion_at_rest():
    robot = CallbackRobot(PANDA.postures["elbow_up"].q)
    panda, result = run_panda(robot)
    commands = np.array(robot.commands)
    assert robot.motions == 1 and not robot.running
    assert result.watchdog_trips == 0 and result.cycles == len(commands)
    assert np.max(np.abs(commands[len(commands) // 2])) > 0.01 and np.all(commands[-1] == 0.0)
    assert np.array_equal(result.log.dq_cmd, commands)  # the log holds what the robot received
    assert_within_limits(commands)
    assert panda.report()["missed_packets"] == 0


def test_a_non_finite_state_trips_the_watchdog_inside_the_callback_and_brakes_continuously():
    robot = CallbackRobot(PANDA.postures["elbow_up"].q, fault="nan", at=60)
    _, result = run_panda(robot)
    assert result.watchdog_trips == 1 and "non-finite" in result.watchdog_reason
    commands = np.array(robot.commands)
    assert np.all(commands[-1] == 0.0) and not robot.running
    assert_within_limits(commands)


@pytest.mark.parametrize("recover", [False, True])
def test_a_reflex_ends_the_run_is_named_and_recovered_only_on_request(recover):
    robot = CallbackRobot(PANDA.postures["elbow_up"].q, fault="reflex", at=40)
    panda, result = run_panda(robot, RobotConfig(automatic_error_recovery=recover))
    assert result.watchdog_reason.startswith("robot error: RuntimeError: libfranka: Move command aborted")
    assert result.cycles == 40 and "\n" not in result.watchdog_reason
    assert panda.report()["reflex"] == ["joint_reflex"] and panda.report()["recovered"] == recover
    assert robot.recoveries == int(recover)
