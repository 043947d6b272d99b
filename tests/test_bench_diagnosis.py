"""Scoring of the diagnosis benchmark's cases (scenarios/bench/diagnosis.py), without simulation."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.scenarios.bench.diagnosis import COMBINED, OUT_OF_FAMILY, accuracy_of, hidden_cases
from impactqp.sim.causes import CAUSE_NAMES, SENSOR_CAUSE_NAMES, JointVelocityScaleCause, VelocityScaleCause


def test_the_fixed_cases_hold_three_combined_and_three_sensor_cases():
    cases = hidden_cases()
    assert sum(len(c) > 1 for c in cases) >= 3 and len(COMBINED) >= 3
    assert sum(all(n in SENSOR_CAUSE_NAMES for n in c) for c in cases) >= 3
    assert all(set(c) <= set(CAUSE_NAMES) for c in cases + list(OUT_OF_FAMILY))


def interval_entries(cause, theta, half):
    return [{"cause": cause.name, "parameter": label, "value": v, "interval": [v - half, v + half]}
            for label, v in zip(cause.labels, theta)]


@settings(deadline=None)
@given(st.floats(0.8, 1.3), st.floats(1e-3, 0.1))
def test_a_refined_velocity_scale_is_scored_per_joint_against_the_global_truth(scale, half):
    """A global scale hidden and named per joint: each joint's value is compared with the global
    truth, and covered when its interval holds it."""
    truth = VelocityScaleCause().overrides(np.array([scale]))
    finer = JointVelocityScaleCause()
    theta = np.full(7, scale)
    result = {"causes": ["velocity_scale"], "parameters": finer.overrides(theta),
              "parameter_intervals": interval_entries(finer, theta, half)}
    named, errors, covered = accuracy_of(("velocity_scale",), result, truth)
    assert named and len(errors) == 7 and max(errors) < 1e-9 and all(covered)


def test_a_missed_cause_counts_as_an_infinite_error_and_uncovered():
    truth = VelocityScaleCause().overrides(np.array([1.1]))
    result = {"causes": [], "parameters": {}, "parameter_intervals": []}
    named, errors, covered = accuracy_of(("velocity_scale",), result, truth)
    assert not named and errors == [float("inf")] and covered == [False]
