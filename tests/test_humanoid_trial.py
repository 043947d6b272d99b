"""One simulated hand impact of the standing G1 (sim/humanoid_trial.py)."""

import numpy as np
import pytest

from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.humanoid_trial import CONTROL_PERIOD, NORMAL, SERVO_GAIN, _Servo, run_impact_trial

GRAVITY = np.array([0.0, 0.0, -9.81])


@pytest.fixture(scope="module")
def trial():
    return run_impact_trial(FloatingBaseModel(), STANCES["parallel"], 0.2)


def test_linear_momentum_of_the_simulated_robot_balances_the_external_impulses(trial):
    """m dc = wall impulse + floor impulse + m g T over the measurement window (joint torques are internal)."""
    mass = FloatingBaseModel().terms(np.r_[0, 0, 0, 0, 0, 0, 1, np.zeros(29)]).mass
    external = trial.impulse + trial.floor_impulse + mass * GRAVITY * trial.duration
    np.testing.assert_allclose(mass * trial.measured_com_jump, external, atol=0.01 * np.linalg.norm(trial.impulse))


def test_the_wall_pushes_the_hand_back_and_the_robot_stands(trial):
    assert trial.impulse @ NORMAL > 0.0
    assert trial.contact_speed > 0.0
    assert trial.duration > 0.0
    assert not trial.fell and not trial.slipped and not trial.lifted


def test_every_predictor_is_reported_with_its_error(trial):
    for method in (*METHODS, "momentum"):
        error = np.mean(np.abs(trial.predicted_jump[method][6:] - trial.measured_jump[6:]))
        assert trial.errors[method] == pytest.approx(error)
        assert trial.predicted_impulse[method] @ NORMAL > 0.0
    np.testing.assert_array_equal(trial.predicted_impulse["momentum"], trial.impulse)


def test_failures_are_consistent_with_the_measured_flags(trial):
    assert trial.feasible == (not trial.failures)
    assert (trial.first_failure == "") == (not trial.failures)
    assert ("foot_slip" in trial.failures) == trial.slipped
    assert ("foot_lift" in trial.failures) == trial.lifted
    assert ("fell" in trial.failures) == trial.fell
    assert ("joint_velocity" in trial.failures) == (trial.max_velocity_ratio > 1.0)
    assert trial.q_log.shape[1] == 36 and 0 < trial.contact_index < len(trial.q_log)


def test_the_servo_torque_saturates_at_the_urdf_effort_limits():
    """A command far beyond what the motors can give is clipped at each joint's effort limit."""
    robot = FloatingBaseModel()
    q = stance_posture(robot, STANCES["parallel"])
    scene = build_humanoid_scene(robot, wall_x=1.0)
    scene.set_state(q)
    servo = _Servo(scene, robot, q, SERVO_GAIN)
    tau = servo.torque(np.full(29, 1e3), CONTROL_PERIOD)
    np.testing.assert_allclose(np.abs(tau), robot.model.effortLimit[6:])
