"""The nominal simulation's and the predictors' errors on measured trials (sim/diagnosis/comparison.py)."""

from dataclasses import replace

import numpy as np
import pytest
from diagnosis_checks import synthetic_trial
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.sim.diagnosis import ReplaySetting
from impactqp.sim.diagnosis.comparison import error_analysis, predictor_errors


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 3.0), st.integers(2, 8))
def test_a_simulation_that_scales_every_jump_has_that_ratio_and_its_errors(seed, scale, count):
    rng = np.random.default_rng(seed)
    speeds = rng.choice([0.08, 0.12, 0.18], count)
    trials = [synthetic_trial(rng, speed=float(v), posture=rng.choice(["elbow_up", None])) for v in speeds]
    measured = np.array([t.jump for t in trials])
    analysis = error_analysis(trials, scale * measured)
    np.testing.assert_allclose(analysis["per_joint_sim_to_measured_ratio"], scale)
    np.testing.assert_allclose(analysis["per_joint_mean_error"], (scale - 1) * measured.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(analysis["per_joint_mean_abs_error"], abs(scale - 1) * np.abs(measured).mean(axis=0))
    assert sum(analysis["per_joint_error_share"]) == pytest.approx(1.0 if scale != 1.0 else 0.0)
    groups = analysis["per_posture_speed"]
    assert set(groups) == {t.posture or "unknown" for t in trials}
    assert {k for g in groups.values() for k in g} == {f"{v:.3f}" for v in speeds}


def test_the_error_slope_follows_errors_that_grow_with_speed():
    rng = np.random.default_rng(3)
    trials = [synthetic_trial(rng, speed=v) for v in (0.1, 0.2, 0.3)]
    nominal = np.array([t.jump + 2.0 * t.reference_speed for t in trials])  # (26) = 2 v
    assert error_analysis(trials, nominal)["error_vs_speed_slope"] == pytest.approx(2.0)


def test_a_predictor_that_made_the_measured_jumps_has_no_error():
    """Trials whose measured jump is a predictor's own prediction: that predictor's error is 0,
    with its own impulse; fed the measured impulse only where a force log exists."""
    rng = np.random.default_rng(5)
    q = PANDA.postures["elbow_up"].q
    trials = [synthetic_trial(rng, force=force) for force in (True, False)]
    trials = [replace(t, q_pre=q + rng.normal(0.0, 0.01, JOINTS), dq_pre=rng.normal(0.0, 0.1, JOINTS)) for t in trials]
    _, _, predictions = predictor_errors(trials, ReplaySetting(DEFAULT_WALL))
    for method in METHODS:
        made = [replace(t, jump=jump) for t, jump in zip(trials, predictions[method])]
        own, fed, again = predictor_errors(made, ReplaySetting(DEFAULT_WALL))
        assert own[method] == pytest.approx(0.0, abs=1e-12)
        assert set(own) == set(METHODS) and set(fed) == set(METHODS)
        np.testing.assert_array_equal(again[method], predictions[method])
