"""The franka adapter maps pylibfranka's RobotState and JointVelocities faithfully."""

from types import SimpleNamespace

import numpy as np
import pytest

from impactqp.controller.model.robot import NQ
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.robot.franka_backend import CollisionThresholds, FrankaRobot, franka_command, state_from_franka

pylibfranka = pytest.importorskip("pylibfranka", reason="pylibfranka is not installed: pip install -e '.[franka]'")

READ_ATTRIBUTES = ("time", "q", "dq", "tau_J", "tau_ext_hat_filtered")


def franka_like_state(t):
    """An object with RobotState's attribute names (RobotState has no Python constructor)."""
    rng = np.random.default_rng(1)
    values = {name: list(rng.normal(size=NQ)) for name in READ_ATTRIBUTES[1:]}
    return SimpleNamespace(time=t, O_F_ext_hat_K=[0.0] * 6, **values), values


def test_the_adapter_reads_only_attributes_that_robotstate_has():
    names = set(dir(pylibfranka.RobotState))
    assert set(READ_ATTRIBUTES) <= names
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
    dq = np.linspace(-0.3, 0.3, NQ)
    command = franka_command(pylibfranka, dq)
    assert isinstance(command, pylibfranka.JointVelocities)
    assert np.allclose(command.dq, dq) and not command.motion_finished
    assert franka_command(pylibfranka, np.zeros(NQ), finished=True).motion_finished


def test_collision_thresholds_have_the_sizes_set_collision_behavior_takes():
    thresholds = CollisionThresholds()
    assert len(thresholds.lower_torque) == len(thresholds.upper_torque) == NQ
    assert len(thresholds.lower_force) == len(thresholds.upper_force) == 6
    assert all(lo <= hi for lo, hi in zip(thresholds.lower_torque, thresholds.upper_torque))


def test_no_robot_at_the_address_is_bad_input():
    with pytest.raises(BadInputError, match="no robot answers at 127.0.0.1"):
        FrankaRobot("127.0.0.1")
