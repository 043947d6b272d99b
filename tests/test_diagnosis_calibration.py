"""Coverage of known truths by a diagnosis's intervals (sim/diagnosis/calibration.py)."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import ArmatureCause, FrictionCause, VelocityScaleCause, per_group
from impactqp.sim.diagnosis.calibration import coverage, covered


def row(cause: str, interval) -> dict:
    return {"cause": cause, "parameter": "", "value": 0.0, "interval": interval}


def test_a_truth_counts_when_its_interval_holds_it_and_a_missed_cause_holds_none():
    """A tiny case: armature (two groups) named, one group's interval holding its truth and one
    not; friction hidden but not named; an open side holds everything beyond it."""
    truth = {"armature": per_group((0.3, 0.1), JOINTS), "friction": 0.4}
    result = {"causes": ["armature"], "parameter_intervals": [row("armature", [0.25, 0.35]), row("armature", [0.12, None])]}
    found = covered([ArmatureCause(JOINTS), FrictionCause()], result, truth)
    assert found == {"armature": [True, False], "friction": [False]}
    open_above = {"causes": ["friction"], "parameter_intervals": [row("friction", [0.3, None])]}
    assert covered([FrictionCause()], open_above, truth) == {"friction": [True]}


def test_a_refined_cause_is_read_per_joint():
    scales = [1.0, 1.0, 1.0, 1.1, 1.0, 1.0, 1.0][:JOINTS]
    truth = {"sensor_velocity_scale": 1.0, "sensor_joint_velocity_scale": scales}
    intervals = [[0.98, 1.02]] * JOINTS
    intervals[3] = [1.05, 1.08]  # misses 1.1
    result = {"causes": ["velocity_scale"], "parameter_intervals": [row("velocity_scale", i) for i in intervals]}
    held = covered([VelocityScaleCause(JOINTS)], result, truth)["velocity_scale"]
    assert held == [j != 3 for j in range(JOINTS)]


@given(st.lists(st.lists(st.booleans(), min_size=1, max_size=4), min_size=1, max_size=10))
def test_coverage_is_the_share_of_truths_held_over_all_datasets(held):
    results = [{"armature": h} for h in held]
    flat = [x for h in held for x in h]
    assert coverage(results) == {"armature": pytest.approx(sum(flat) / len(flat))}
