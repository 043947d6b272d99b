"""The collision thresholds of a robot run: the predicted peaks from first principles (the
generalized-momentum impulse iota = v n / (n^T J M^-1 J^T n), the impulsive torque J^T iota and
the contact wrench, over delta_t), linear in the asked speed; the thresholds k times the peaks
between the defaults and the table's bound; a list the table gives wins; "fixed" keeps the
lists."""

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.robot_config import (
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    MAX_COLLISION_FORCE,
    MAX_COLLISION_TORQUE,
    RobotConfig,
)
from impactqp.controller.runtime.collision_thresholds import fixed_thresholds, impact_thresholds, predicted_peaks

ROBOT = "fr3"
MODEL = RobotModel(ROBOT)
POSTURES = ROBOTS[ROBOT].postures
SURFACE = POSTURES["elbow_up"].surface
Q_START = approach_start(MODEL, POSTURES["elbow_up"].q, SURFACE, 0.05)
IMPACT = ControllerConfig.approach(SURFACE, 0.15).impact


def test_the_peaks_are_the_momentum_impulse_over_the_impact_duration():
    """gm: iota = -(n n^T / (n^T W n)) v- with W = J M^-1 J^T and n . v- = -v (eq. (12), (22))."""
    v = 0.2
    peaks = predicted_peaks(MODEL, Q_START, SURFACE.normal, v, replace(IMPACT, jump_model="gm"))
    model = MODEL.model
    data = model.createData()
    M = pin.crba(model, data, Q_START)
    M = np.triu(M) + np.triu(M, 1).T
    frame = MODEL.contact_frame_id
    J = pin.computeFrameJacobian(model, data, Q_START, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    n = SURFACE.normal
    iota = v * n / (n @ J @ np.linalg.solve(M, J.T) @ n)
    dt = IMPACT.impact_duration
    np.testing.assert_allclose(peaks.impulse, iota, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(peaks.torque, np.abs(J.T @ iota) / dt, rtol=1e-9, atol=1e-9)
    pin.framesForwardKinematics(model, data, Q_START)
    r = data.oMf[frame].translation - data.oMf[model.getFrameId(MODEL.description.flange_frame)].translation
    np.testing.assert_allclose(peaks.wrench, np.abs(np.concatenate([iota, np.cross(r, iota)])) / dt, rtol=1e-9, atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(posture=st.sampled_from(sorted(POSTURES)), v=st.floats(0.01, 1.5), scale=st.floats(1.1, 4.0))
def test_the_thresholds_scale_with_the_speed_until_their_bounds_and_exceed_the_peaks_by_the_factor(posture, v, scale):
    surface = POSTURES[posture].surface
    q = approach_start(MODEL, POSTURES[posture].q, surface, 0.05)
    table = RobotConfig()
    k = table.impact_threshold_factor
    slow, fast = (predicted_peaks(MODEL, q, surface.normal, speed, IMPACT) for speed in (v, scale * v))
    np.testing.assert_allclose(fast.torque, scale * slow.torque, rtol=1e-9, atol=1e-12)  # the impulse is linear in v
    np.testing.assert_allclose(fast.wrench, scale * slow.wrench, rtol=1e-9, atol=1e-12)
    for peaks in (slow, fast):
        thresholds = impact_thresholds(table, peaks)
        assert thresholds.lower_torque == thresholds.upper_torque and thresholds.lower_force == thresholds.upper_force
        for threshold, peak, default, bound in (
            (thresholds.upper_torque, peaks.torque, DEFAULT_TORQUE_THRESHOLDS, MAX_COLLISION_TORQUE),
            (thresholds.upper_force, peaks.wrench, DEFAULT_FORCE_THRESHOLDS, MAX_COLLISION_FORCE),
        ):
            threshold = np.asarray(threshold)
            assert np.all(threshold >= np.asarray(default)) and np.all(threshold <= bound)
            free = k * peak <= bound
            assert np.all(threshold[free] >= k * peak[free] * (1 - 1e-12))  # k times above the peak
            between = (k * peak > np.asarray(default)) & free
            np.testing.assert_allclose(threshold[between], k * peak[between], rtol=1e-12)
    both = (k * slow.torque > np.asarray(DEFAULT_TORQUE_THRESHOLDS)) & (k * fast.torque <= MAX_COLLISION_TORQUE)
    ratio = np.asarray(impact_thresholds(table, fast).upper_torque)[both] / np.asarray(impact_thresholds(table, slow).upper_torque)[both]
    np.testing.assert_allclose(ratio, scale, rtol=1e-9)  # linear in the speed between the bounds


def test_a_list_the_table_gives_wins_and_fixed_keeps_the_lists():
    peaks = predicted_peaks(MODEL, Q_START, SURFACE.normal, 0.6, IMPACT)
    upper = [150.0] * 7
    table = RobotConfig(upper_torque_thresholds=upper, lower_force_thresholds=[90.0] * 6)
    computed = impact_thresholds(RobotConfig(), peaks)
    thresholds = impact_thresholds(table, peaks)
    assert thresholds.upper_torque == upper and thresholds.lower_force == [90.0] * 6
    assert thresholds.lower_torque == computed.lower_torque
    # the computed upper list, raised where the given lower one is above it (lower <= upper)
    assert thresholds.upper_force == np.maximum(computed.upper_force, 90.0).tolist()
    assert any(x < 90.0 for x in computed.upper_force) and any(x > 90.0 for x in computed.upper_force)
    assert "table's lists" in thresholds.reason
    fixed = impact_thresholds(RobotConfig(collision_thresholds="fixed"), peaks)
    assert fixed == fixed_thresholds(RobotConfig()) and fixed.upper_torque == DEFAULT_TORQUE_THRESHOLDS
    assert impact_thresholds(RobotConfig(), None) == fixed  # no impact planned: the defaults
    assert fixed_thresholds(table).upper_torque == upper and fixed_thresholds(table).lower_torque == DEFAULT_TORQUE_THRESHOLDS


def test_the_reason_is_one_line_with_the_speed_the_factor_and_the_values():
    peaks = predicted_peaks(MODEL, Q_START, SURFACE.normal, 0.3, IMPACT)
    thresholds = impact_thresholds(RobotConfig(impact_threshold_factor=2.5), peaks)
    assert "\n" not in thresholds.reason
    assert "0.300 m/s" in thresholds.reason and "times 2.5" in thresholds.reason
    assert f"{thresholds.upper_force[0]:.0f}" in thresholds.reason
    with pytest.raises(ValueError):
        np.asarray(thresholds.upper_torque).reshape(6)  # one per joint
