"""Closed-loop impact trials with the QP controller: state feedback, contact speed, observed
criteria and predictions, process pool."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.measured.impact import ImpactNotFoundError, measure_impact
from impactqp.sim.runner import OBSERVATION_WINDOW, TrialSpec, run_approach
from impactqp.scenarios.trial import TrialPool, TrialRunner

POSTURE = "elbow_right"
Q = PANDA.postures[POSTURE].q


@pytest.fixture(scope="module")
def runner():
    return TrialRunner.build(DEFAULT_WALL)


@pytest.fixture(scope="module")
def result(runner):
    return runner.run(TrialSpec(POSTURE, Q, 0.15))


def test_commanded_state_feedback_reproduces_the_kinematic_approach(runner, result):
    """Fed its own command, the controller at constant speed hits like the sim core's
    Cartesian approach command: same jump, same contact duration."""
    baseline = measure_impact(run_approach(runner.scene, runner.robot, TrialSpec(POSTURE, Q, 0.15)).log)
    np.testing.assert_allclose(result.impact.dq_jump, baseline.dq_jump, atol=5e-3)
    assert result.impact.duration == pytest.approx(baseline.duration, abs=1e-3)
    assert result.impact.duration > 0.010
    assert result.fallback_count == 0


def test_measured_state_feedback_cuts_the_contact_short(runner, result):
    """The documented failure of feeding the measured state through the servo's feed-forward:
    the robot recoils and the contact lasts a few ms only."""
    measured = runner.run(TrialSpec(POSTURE, Q, 0.15, feedback="measured"))
    assert measured.impact.duration < 0.25 * result.impact.duration
    assert np.linalg.norm(measured.impact.impulse) < 0.5 * np.linalg.norm(result.impact.impulse)


def test_contact_speed_is_the_reference_speed(result, runner):
    assert result.contact_speed == pytest.approx(0.15, rel=0.01)
    from_rest = runner.run(TrialSpec(POSTURE, Q, 0.12, start_at_rest=True, start_distance=0.05))
    assert from_rest.contact_speed == pytest.approx(0.12, rel=0.02)


def test_observed_criteria_follow_their_definitions(result, runner):
    robot, log, impact = runner.robot, result.log, result.impact
    window = (log.t >= impact.t_contact_start) & (log.t <= impact.t_contact_start + OBSERVATION_WINDOW + 1e-9)
    assert result.max_velocity_ratio == pytest.approx(np.max(np.abs(log.dq[window]) / robot.dq_max))
    terms = robot.terms(impact.q_pre, impact.dq_pre)
    # the impulse is the integral of the logged contact force over the first contact phase
    phase = (log.force_t >= impact.t_contact_start - 1e-9) & (log.force_t < impact.t_contact_start + impact.duration)
    np.testing.assert_allclose(impact.impulse, log.force[phase].sum(axis=0) * runner.scene.timestep, rtol=0.01)
    torque = np.abs(terms.J.T @ impact.impulse) / impact.duration
    assert result.max_torque_ratio == pytest.approx(np.max(torque / robot.tau_max))
    assert result.violated == (result.max_velocity_ratio > 1 or result.max_torque_ratio > 1)
    v = terms.J @ impact.dq_pre
    assert result.contact_speed == pytest.approx(-DEFAULT_WALL.normal @ v)
    for name in METHODS:
        expected = JUMP_MODELS[name].predict(terms, DEFAULT_WALL.normal, v, 0.0).dq_jump
        np.testing.assert_allclose(result.predicted[name], expected)


def test_json_report_shapes(result):
    report = result.to_json()
    assert len(report["impulse"]) == 3 and len(report["dq_jump"]) == JOINTS
    assert set(report["predicted"]) == {"classical", "classical_normal", "gm", "crb"}
    assert all(len(v) == JOINTS for v in report["predicted"].values())
    assert np.dot(report["impulse"], DEFAULT_WALL.normal) > 0  # the wall pushes the robot back


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"normal_speed": 0.0}, r"\(0, 3\] m/s"),
        ({"normal_speed": -0.1}, r"\(0, 3\] m/s"),
        ({"jump_model": "magic"}, "unknown jump model"),
        ({"feedback": "psychic"}, "feedback"),
        ({"after_contact": 0.01}, "after_contact"),
        ({"restitution": 1.5}, r"\[0, 1\]"),
    ],
)
def test_bad_specs_are_rejected(changes, message):
    values = {"posture": POSTURE, "q_contact": Q, "normal_speed": 0.1} | changes
    with pytest.raises(ValueError, match=message):
        TrialSpec(**values)


def test_trial_id_names_the_setting():
    assert TrialSpec(POSTURE, Q, 0.15).trial_id == "elbow_right_vn150_free"
    spec = TrialSpec(POSTURE, Q, 0.12, np.array([0.0, -0.03, 0.0]), jump_model="crb")
    assert spec.trial_id == "elbow_right_vn120_vt0_m30_0_crb"


def test_pool_of_two_processes_gives_the_same_trials(result):
    specs = [TrialSpec(POSTURE, Q, 0.15), TrialSpec("elbow_up", PANDA.postures["elbow_up"].q, 0.18)]
    with TrialPool(DEFAULT_WALL, jobs=2) as pool:
        results = list(pool.map(specs))
    assert [r.trial_id for r in results] == [s.trial_id for s in specs]
    np.testing.assert_array_equal(results[0].log.dq, result.log.dq)


def test_a_trial_whose_tool_never_touches_the_wall_says_so(runner):
    """Cut short before the contact (a third of the time the approach needs at its speed), a trial
    has no impact, and the error says what the trial did, not what the torque residual did not."""
    spec = TrialSpec(POSTURE, Q, 0.15)
    run = run_approach(runner.scene, runner.robot, spec, runner.source_of(spec), spec.start_distance / 0.15 / 3)
    assert not run.log.force.any()
    with pytest.raises(ImpactNotFoundError, match=rf"never touched the wall: the simulated trial lasted 0\.\d+ s from "
                                                  rf"{spec.start_distance:.3f} m in front of it at a commanded 0\.150 m/s"):
        runner.evaluate(spec, run.log)
