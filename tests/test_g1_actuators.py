"""The G1's reflected rotor inertias (controller/model/g1_actuators.py)."""

import numpy as np
import pytest

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.g1_actuators import JOINT_MOTORS, MOTORS, joint_armature, joint_kind
from impactqp.controller.model.validation import BadInputError


@pytest.fixture(scope="module")
def robot():
    return RobotModel("g1")


def test_two_stage_planetary_formula_by_hand():
    """5020: g2 g3 = (64 / 18)(72 / 16) = 16, g3^2 = 20.25:
    0.139e-4 * 256 + 0.017e-4 * 20.25 + 0.169e-4 = 36.09725e-4; 4010: 0.068e-4 * 25^2 = 4.25e-3."""
    assert MOTORS["5020"].armature == pytest.approx(36.09725e-4, rel=1e-12)
    assert MOTORS["4010"].armature == pytest.approx(4.25e-3, rel=1e-12)
    assert MOTORS["7520-22"].armature == pytest.approx(0.489e-4 * 22.5**2 + 0.109e-4 * 25 + 0.738e-4, rel=1e-12)


def test_every_joint_of_the_g1_is_mapped(robot):
    armature = joint_armature(robot.joint_names)
    assert armature.shape == (len(robot.joint_names),)
    assert np.all(armature > 0.0)
    assert {joint_kind(name) for name in robot.joint_names} == set(JOINT_MOTORS)


def test_left_and_right_joints_get_the_same_armature(robot):
    armature = dict(zip(robot.joint_names, joint_armature(robot.joint_names)))
    for name, value in armature.items():
        if name.startswith("left_"):
            assert armature["right_" + name.removeprefix("left_")] == value


def test_joints_with_the_same_urdf_effort_limit_share_a_drive(robot):
    """The URDF's torque limits name the drive independently: 88 N m (7520-14), 139 N m (7520-22),
    35 N m (two 5020 through a linkage), 25 N m (5020), 5 N m (4010)."""
    armature = joint_armature(robot.joint_names)
    effort = robot.model.effortLimit[robot.base_nv:]
    for limit in np.unique(effort):
        assert np.ptp(armature[effort == limit]) == 0.0
    assert len(np.unique(armature)) == len(np.unique(effort))


def test_an_unknown_joint_is_bad_input():
    with pytest.raises(BadInputError, match="no G1 actuator"):
        joint_armature(["left_finger_joint"])


def test_the_description_s_acceleration_limits_are_the_actuators(robot):
    """ddq_max of g1.toml is acceleration_limits over the stances, rounded down, each within the
    share of its torque over the joint's own inertia (M_ii + armature, the base welded); the jerk
    limit gives a swing of JERK_HORIZON."""
    from impactqp.controller.model.g1_actuators import JERK_HORIZON, TORQUE_SHARE, acceleration_limits
    from impactqp.controller.model.humanoid_stance import STANCES, stance_posture

    postures = [stance_posture(robot, s) for s in STANCES.values()]
    np.testing.assert_array_equal(robot.ddq_max, np.floor(acceleration_limits(robot, postures)))
    np.testing.assert_allclose(robot.ddq_max / robot.dddq_max, JERK_HORIZON, rtol=1e-12)
    for q in postures:
        M = robot.terms(q).M
        welded = TORQUE_SHARE * robot.tau_max / (np.diag(M)[robot.base_nv:] + joint_armature(robot.joint_names))
        assert np.all(robot.ddq_max <= welded)
