"""The ``[libfranka]`` table: defaults a robot accepts, every entry checked with a one-line reason."""

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.robot_config import DEFAULT_FORCE_THRESHOLDS, DEFAULT_TORQUE_THRESHOLDS, RobotConfig

DOCS = Path(__file__).resolve().parents[1] / "docs" / "robot-loop.md"
TOML_FENCE = re.compile(r"^```toml[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)


def test_the_defaults_have_the_sizes_libfranka_takes_and_round_trip():
    robot = RobotConfig()
    assert len(DEFAULT_TORQUE_THRESHOLDS) == len(robot.joint_impedance) == JOINTS and len(DEFAULT_FORCE_THRESHOLDS) == 6
    assert robot.collision_thresholds == "from_impact" and robot.impact_threshold_factor > 1.0
    assert robot.lower_torque_thresholds is robot.upper_force_thresholds is None  # from the impact, or the defaults
    assert robot.load_mass is robot.load_com is robot.load_inertia is None  # the declared tool's load
    assert not robot.automatic_error_recovery  # off unless asked for
    config = ControllerConfig.from_dict({"libfranka": {"load_mass": 0.4, "load_com": [0.0, 0.0, 0.05]}})
    assert ControllerConfig.from_dict(config.to_dict()).libfranka == config.libfranka


@pytest.mark.parametrize(
    "entry, reason",
    [
        ({"joint_impedance": [3000.0] * (JOINTS - 1)}, f"libfranka.joint_impedance must be {JOINTS} numbers"),
        ({"joint_impedance": [0.0] * JOINTS}, "libfranka.joint_impedance must lie in"),
        (
            {"lower_torque_thresholds": [200.0] * JOINTS, "upper_torque_thresholds": [100.0] * JOINTS},
            "must not exceed libfranka.upper_torque_thresholds",
        ),
        ({"lower_force_thresholds": [100.0] * 5}, "libfranka.lower_force_thresholds must be 6 numbers"),
        ({"collision_thresholds": "measured"}, "libfranka.collision_thresholds = 'measured'; choose from from_impact, fixed"),
        ({"impact_threshold_factor": 0.5}, "libfranka.impact_threshold_factor"),
        ({"impact_threshold_factor": 20.0}, "libfranka.impact_threshold_factor"),
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


def test_the_libfranka_examples_of_the_robot_loop_docs_load():
    """Every ``toml`` block of docs/robot-loop.md with a ``[libfranka]`` table is a configuration
    that loads, and the collision-threshold keys it sets are the ones loaded."""
    blocks = [tomllib.loads(code) for code in TOML_FENCE.findall(DOCS.read_text(encoding="utf-8"))]
    tables = [block["libfranka"] for block in blocks if "libfranka" in block]
    assert {table.get("collision_thresholds") for table in tables} >= {"from_impact", "fixed"}
    for table in tables:
        loaded = ControllerConfig.from_dict({"libfranka": table}).libfranka
        for key, value in table.items():
            assert getattr(loaded, key) == value, key
