"""The ``[libfranka]`` table: defaults a robot accepts, every entry checked with a one-line reason."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import RobotConfig


def test_the_defaults_have_the_sizes_libfranka_takes_and_round_trip():
    robot = RobotConfig()
    assert len(robot.lower_torque_thresholds) == len(robot.upper_torque_thresholds) == len(robot.joint_impedance) == JOINTS
    assert len(robot.lower_force_thresholds) == len(robot.upper_force_thresholds) == 6
    assert robot.load_mass is robot.load_com is robot.load_inertia is None  # the declared tool's load
    assert not robot.automatic_error_recovery  # off unless asked for
    config = ControllerConfig.from_dict({"libfranka": {"load_mass": 0.4, "load_com": [0.0, 0.0, 0.05]}})
    assert ControllerConfig.from_dict(config.to_dict()).libfranka == config.libfranka


@pytest.mark.parametrize(
    "entry, reason",
    [
        ({"joint_impedance": [3000.0] * (JOINTS - 1)}, f"libfranka.joint_impedance must be {JOINTS} numbers"),
        ({"joint_impedance": [0.0] * JOINTS}, "libfranka.joint_impedance must lie in"),
        ({"lower_torque_thresholds": [200.0] * JOINTS}, "must not exceed libfranka.upper_torque_thresholds"),
        ({"upper_force_thresholds": [np.nan] * 6}, "must be finite"),
        ({"load_mass": 4.0}, "libfranka.load_mass"),
        ({"load_com": [2.0, 0.0, 0.0]}, "libfranka.load_com"),
        ({"load_inertia": [1e-3, 1e-3, 0, 0, 1e-3, 0, 0, 0, 1e-3]}, "symmetric positive semi-definite"),
        ({"automatic_error_recovery": "yes"}, "libfranka.automatic_error_recovery"),
        ({"max_model_difference": 0.0}, "libfranka.max_model_difference"),
        ({"stiffness": 1.0}, "unknown keys in [libfranka]: stiffness"),
    ],
)
def test_bad_entries_are_bad_input_naming_the_key(entry, reason):
    with pytest.raises(BadInputError) as error:
        ControllerConfig.from_dict({"libfranka": entry})
    assert reason in str(error.value) and "\n" not in str(error.value)
