"""The one trial result of every robot (sim/trial_result.py), on results built by hand: the
error (26) over the joints, the failures derived from the criteria, the dataset trial's frame."""

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.measured.impact import ImpactMeasurement
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.sim.observed_criteria import Observed
from impactqp.sim.trial_result import LIFT, SLIP, HeldContactResult, TrialResult

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
