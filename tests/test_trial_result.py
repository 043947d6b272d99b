"""The one trial result of every robot (sim/trial_result.py), on results built by hand (the
error (26) over the joints, the predicted post-impact velocity (19), the failures derived from
the criteria, the dataset trial's frame),
and a standing robot's measurement on a simulated G1 trial (its momentum balance, predictors,
failures and equivalent duration)."""

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.measured.impact import ImpactMeasurement
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.sim.humanoid_feet import CONE_TOLERANCE, LIFT_MARGIN, SLIP_SPEED
from impactqp.sim.observed_criteria import Observed
from impactqp.sim.runner import NORMAL, run_impact_trial
from impactqp.sim.trial_result import LIFT, SLIP, HeldContactResult, TrialResult

GRAVITY = np.array([0.0, 0.0, -9.81])

STEPS, JOINTS = 5, 3
finite = st.floats(-10.0, 10.0, allow_nan=False)


def result(base_nv: int = 0, measured=None, predicted=None, criteria=None, held=None) -> TrialResult:
    nv = base_nv + JOINTS
    zeros = np.zeros((STEPS, JOINTS))
    base = np.arange(STEPS * 13, dtype=float).reshape(STEPS, 13) if base_nv else np.zeros((0, 13))
    log = TrialLog(0.001 * np.arange(STEPS), zeros, zeros, zeros, zeros, base=base)
    impact = ImpactMeasurement("force", 0.002, 0.002, 2, 2, 3, (2, 2), np.zeros(JOINTS), np.zeros(JOINTS),
                               np.zeros(JOINTS), np.zeros(JOINTS), np.array([-1.0, 0.0, 0.0]), 0.001)
    return TrialResult(
        trial_id="a_vn100_free", posture="a", normal_speed=0.1, tangential_velocity=np.zeros(3), jump_model=None,
        log=log, impact=impact, measured_jump=np.zeros(nv) if measured is None else measured,
        contact_speed=0.1, predicted=predicted or {}, criteria=criteria or {}, held=held,
    )


def held_part(wall_x: float = 0.7, foot_slip: float = 0.0, foot_lift: float = 0.0) -> HeldContactResult:
    return HeldContactResult(
        peak_force=500.0, floor_impulse=np.zeros(3), measured_com_jump=np.zeros(3), predicted_com_jump={},
        predicted_impulse={}, post_com_velocity=np.zeros(3), foot_slip=foot_slip, foot_lift=foot_lift,
        slide_speed=0.0, wall_x=wall_x, wall_normal=np.array([-1.0, 0.0, 0.0]), q_log=np.zeros((STEPS, 10)),
    )


@given(st.sampled_from([0, 6]), arrays(float, 6 + JOINTS, elements=finite), arrays(float, 6 + JOINTS, elements=finite))
def test_errors_are_eq_26_over_the_joints_only(base_nv, measured, predicted):
    """e = (1/D) sum_i |predicted_i - measured_i| over the D joints; a floating base's rows do not count."""
    nv = base_nv + JOINTS
    trial = result(base_nv, measured[:nv], {"crb": predicted[:nv]})
    expected = sum(abs(predicted[base_nv + i] - measured[base_nv + i]) for i in range(JOINTS)) / JOINTS
    assert math.isclose(trial.errors["crb"], expected, rel_tol=1e-12, abs_tol=1e-12)
    changed = predicted[:nv].copy()
    changed[:base_nv] += 1.0
    assert result(base_nv, measured[:nv], {"crb": changed}).errors == trial.errors


@given(st.sampled_from([0, 6]), arrays(float, JOINTS, elements=finite), arrays(float, 6 + JOINTS, elements=finite))
def test_the_predicted_post_impact_velocity_is_eq_19_of_the_joints(base_nv, dq_pre, jump):
    """dq+_i = dq-_i + Delta dq_i for each joint i; a floating base's twist rows are not joints."""
    trial = result(base_nv, predicted={"crb": jump[:base_nv + JOINTS]})
    trial.impact.dq_pre[:] = dq_pre
    expected = [dq_pre[i] + jump[base_nv + i] for i in range(JOINTS)]
    assert trial.predicted_post_velocity("crb").tolist() == expected


@given(st.lists(st.tuples(st.booleans(), st.floats(-0.1, 0.1, allow_nan=False)), min_size=1, max_size=4))
def test_failures_derive_from_the_criteria(flags):
    """Violated iff a criterion failed; the first failure has the earliest onset (ties: the list's order)."""
    criteria = {f"c{i}": Observed(f"c{i}", 0.0, failed, onset) for i, (failed, onset) in enumerate(flags)}
    trial = result(criteria=criteria)
    failed = [(onset, i) for i, (f, onset) in enumerate(flags) if f]
    assert trial.violated == bool(failed) == (not trial.feasible)
    assert trial.failures == tuple(f"c{i}" for _, i in sorted(failed, key=lambda p: p[1]))
    assert trial.first_failure == (f"c{min(failed)[1]}" if failed else "")
    if failed:
        assert trial.failure_time == min(failed)[0]
    else:
        assert math.isnan(trial.failure_time)


def test_dataset_trial_moves_a_held_robot_onto_the_wall_plane():
    """A fixed base's log is written as it is; with held contacts the base's x is measured from the wall."""
    arm = result()
    entry, log = arm.dataset_trial()
    assert log is arm.log and entry.id == "a_vn100_free" and entry.impact_time == arm.impact.t_contact_start
    standing = result(base_nv=6, held=held_part(wall_x=0.7))
    _, log = standing.dataset_trial()
    np.testing.assert_array_equal(log.base[:, 0], standing.log.base[:, 0] - 0.7)
    np.testing.assert_array_equal(log.base[:, 1:], standing.log.base[:, 1:])


def test_held_part_slip_lift_and_equivalent_duration():
    """Slipped / lifted beyond SLIP / LIFT; T = n . iota / peak force."""
    criteria = {name: Observed(name, 0.5, False, float("nan")) for name in ("joint_velocity", "fell")}
    trial = result(base_nv=6, criteria=criteria, held=held_part(foot_slip=1.01 * SLIP, foot_lift=0.99 * LIFT))
    assert trial.held.slipped and not trial.held.lifted
    assert trial.equivalent_duration * trial.held.peak_force == trial.held.wall_normal @ trial.impact.impulse
    arm_criteria = ("joint_velocity", "impulsive_torque")
    arm = result(criteria={name: Observed(name, 0.5, False, float("nan")) for name in arm_criteria})
    assert set(arm.to_json()) >= {"posture", "reference_normal_speed", "dq_jump", "violated"}
    report = trial.to_json("g1")
    assert report["robot"] == "g1" and report["reference_speed"] == 0.1 and "foot_slip" in report


@pytest.fixture(scope="module")
def trial():
    """A scripted standing trial of the G1: the parallel stance, 0.2 m/s."""
    return run_impact_trial(RobotModel("g1"), STANCES["parallel"], 0.2)


def test_linear_momentum_of_the_simulated_robot_balances_the_external_impulses(trial):
    """m dc = wall impulse + floor impulse + m g T over the measurement window (joint torques are internal)."""
    robot = RobotModel("g1")
    mass = robot.terms(pin.neutral(robot.model)).mass
    external = trial.impact.impulse + trial.held.floor_impulse + mass * GRAVITY * trial.impact.duration
    atol = 0.01 * np.linalg.norm(trial.impact.impulse)
    np.testing.assert_allclose(mass * trial.held.measured_com_jump, external, atol=atol)


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


def test_the_equivalent_duration_is_at_most_the_contact_duration(trial):
    """A force never above its peak gives at most peak x duration of impulse."""
    assert 0.0 < trial.equivalent_duration <= trial.impact.duration
    assert trial.equivalent_duration * trial.held.peak_force == pytest.approx(trial.impact.impulse @ NORMAL)
