"""One simulated hand impact of the standing G1 (sim/humanoid_trial.py)."""

import numpy as np
import pinocchio as pin
import pytest

from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.sim.humanoid_feet import CONE_TOLERANCE, LIFT_MARGIN, SLIP_SPEED
from impactqp.sim.humanoid_trial import NORMAL, run_impact_trial

GRAVITY = np.array([0.0, 0.0, -9.81])


@pytest.fixture(scope="module")
def trial():
    return run_impact_trial(RobotModel("g1"), STANCES["parallel"], 0.2)


def test_linear_momentum_of_the_simulated_robot_balances_the_external_impulses(trial):
    """m dc = wall impulse + floor impulse + m g T over the measurement window (joint torques are internal)."""
    robot = RobotModel("g1")
    mass = robot.terms(pin.neutral(robot.model)).mass
    external = trial.impact.impulse + trial.held.floor_impulse + mass * GRAVITY * trial.impact.duration
    np.testing.assert_allclose(mass * trial.held.measured_com_jump, external, atol=0.01 * np.linalg.norm(trial.impact.impulse))


def test_the_wall_pushes_the_hand_back_and_the_robot_stands(trial):
    assert trial.impact.impulse @ NORMAL > 0.0
    assert trial.contact_speed > 0.0
    assert trial.impact.duration > 0.0
    assert not trial.fell and not trial.held.slipped and not trial.held.lifted


def test_every_predictor_is_reported_with_its_error(trial):
    for method in (*METHODS, "momentum"):
        joints = slice(RobotModel("g1").base_nv, None)
        error = np.mean(np.abs(trial.predicted[method][joints] - trial.measured_jump[joints]))
        assert trial.errors[method] == pytest.approx(error)
        assert trial.held.predicted_impulse[method] @ NORMAL > 0.0
    np.testing.assert_array_equal(trial.held.predicted_impulse["momentum"], trial.impact.impulse)


def test_failures_are_consistent_with_the_measured_onsets(trial):
    assert trial.feasible == (not trial.failures)
    assert set(trial.failure_times) == set(trial.failures)
    assert (trial.first_failure == "") == (not trial.failures)
    if trial.failures:
        assert trial.failure_time == min(trial.failure_times.values())
    slid = trial.cone_ratio >= 1.0 - CONE_TOLERANCE or trial.held.slide_speed > SLIP_SPEED
    assert ("foot_slip" in trial.failures) == slid
    assert ("foot_lift" in trial.failures) == (trial.cop_margin <= LIFT_MARGIN)
    assert ("capture" in trial.failures) == (trial.capture_margin < 0.0)
    assert ("fell" in trial.failures) == trial.fell
    assert ("joint_velocity" in trial.failures) == (trial.max_velocity_ratio > 1.0)
    assert trial.held.q_log.shape[1] == RobotModel("g1").model.nq and 0 < trial.impact.pre_index < len(trial.held.q_log)


def test_a_slow_impact_leaves_the_feet_flat_and_the_com_capturable(trial):
    """0.2 m/s in the parallel stance: the feet stay loaded, inside their cones and still."""
    assert 0.0 < trial.cone_ratio < 1.0 - CONE_TOLERANCE
    assert trial.held.slide_speed < SLIP_SPEED
    assert trial.capture_margin > 0.0


def test_the_stop_does_not_jolt_the_feet():
    """At the stop the wall has stopped the hand while the reference still moves at the approach
    speed; the held servo does not ask for that reference's deceleration in one step, so a trial at
    about 0.5 m/s of contact speed shows no foot onset (with a zero command alone, the left foot
    unloaded at the stop and slipped)."""
    trial = run_impact_trial(RobotModel("g1"), STANCES["wide"], 0.6)
    assert trial.contact_speed > 0.45
    assert trial.failures == ()


def test_the_equivalent_duration_is_at_most_the_contact_duration(trial):
    """A force never above its peak gives at most peak x duration of impulse."""
    assert 0.0 < trial.equivalent_duration <= trial.impact.duration
    assert trial.equivalent_duration * trial.held.peak_force == pytest.approx(trial.impact.impulse @ NORMAL)
