"""The diagnosis's result: its JSON summary and its message (sim/diagnosis/result.py)."""

from dataclasses import replace

import numpy as np
import pytest
from diagnosis_checks import synthetic_trial
from hypothesis import given
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.model.choice import DEFAULT_CHOICE
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.sim.diagnosis import EXPLAINED_GAIN, Diagnosis, interval_text
from impactqp.sim.diagnosis.noise import FIT_LIMIT
from impactqp.sim.plant import PlantParameters

SUMMARY_KEYS = {
    "cause", "causes", "explained", "parameters", "intervals", "parameter_intervals", "open_sides", "steps",
    "baseline_error", "extended_error", "gain", "candidates", "trials", "skipped", "predictors",
    "predictors_measured_impulse", "analysis", "message", "gain_over_floor", "fit", "nominal_fit",
    "best_model", "trial_residuals", "outlier_trials", "timing",
}
FITS = {"jump": 1.1, "torque": 0.9, "impulse": 0.5, "duration": 0.4, "fits_noise": True}

ends = st.one_of(st.none(), st.floats(-1e3, 1e3))


@given(ends, ends)
def test_an_interval_reads_as_its_closed_ends(low, high):
    text = interval_text([low, high])
    assert ("open below" in text or "both ways" in text) == (low is None)
    assert ("open above" in text or "both ways" in text) == (high is None)
    for end in (low, high):
        if end is not None:
            assert f"{end:.4g}" in text


def diagnosis(explained: bool, baseline: float, extended: float, open_sides: list, fit: dict = FITS,
              nominal_fit: dict = FITS, residuals=(1.0, 1.2)) -> Diagnosis:
    trials = [synthetic_trial(np.random.default_rng(k)) for k in range(len(residuals))]
    trials = [replace(t, id=f"t{k}") for k, t in enumerate(trials)]
    causes = ["friction"] if explained else []
    parameter = {"cause": "friction", "parameter": "friction coefficient", "value": 0.3, "interval": [0.2, None]}
    return Diagnosis(
        trials=trials, skipped=[], nominal_jumps=np.zeros((2, JOINTS)), extended_jumps=np.zeros((2, JOINTS)),
        baseline_errors=np.full(len(trials), baseline), candidates=[], cause="friction", explained=explained,
        parameters={"friction": 0.3}, predictors={}, predictors_measured_impulse={}, predictions={}, analysis={},
        causes=causes, steps=[], intervals={"friction": [0.2, None]}, parameter_intervals=[parameter],
        open_sides=open_sides, extended_error=extended, extended_plant=PlantParameters(), surface=DEFAULT_WALL,
        choice=DEFAULT_CHOICE,
        gain_over_floor=0.1, fit=fit, nominal_fit=nominal_fit, trial_residuals=np.array(residuals),
    )


@given(st.booleans(), st.floats(1e-3, 1.0), st.floats(0.0, 1.0))
def test_the_summary_has_every_key_and_its_gain_is_one_minus_the_error_ratio(explained, baseline, extended):
    summary = diagnosis(explained, baseline, extended, []).summary()
    assert set(summary) == SUMMARY_KEYS
    assert summary["gain"] == pytest.approx(1.0 - extended / baseline)
    assert summary["trials"] == 2 and summary["causes"] == (["friction"] if explained else [])


def test_the_message_names_the_causes_their_intervals_and_what_is_open():
    side = {"cause": "friction", "parameter": "friction coefficient", "side": "above", "fitted": 0.3,
            "negligible": False, "trials_needed": "faster sliding trials"}
    text = diagnosis(True, 0.01, 0.002, [side]).message()
    assert text.startswith("The gap between the simulation and the measurements is explained by 'friction'")
    assert "friction coefficient: 0.3, 95 % interval at least 0.2 (open above)." in text
    assert "cannot bound friction coefficient above: faster sliding trials." in text
    assert "within the noise (jump 1.1, torque 0.9, impulse 0.5, duration 0.4 noise units)" in text
    misfit = {**FITS, "fits_noise": False}
    text = diagnosis(False, 0.01, 0.009, [side], nominal_fit=misfit).message()
    assert text.startswith("No candidate cause explains the gap: the best one, 'friction'")
    assert f"threshold {100 * EXPLAINED_GAIN:.0f} %" in text and "cannot bound" not in text
    needless = diagnosis(False, 0.01, 0.009, [side])
    needless.candidates = [{"cause": "friction", "gain": 0.016}, {"cause": "payload", "gain": -0.2}]
    text = needless.message()
    assert text.startswith("No candidate cause is needed: the nominal simulation already matches the data")
    # a share of the excess over the floor above its threshold (near the floor) is not the reason: the gain is
    assert "lowers the held-out residual by 2 % (a cause needs 20 %)" in text


@given(st.sampled_from(["jump", "torque", "impulse", "duration"]), st.floats(FIT_LIMIT * 1.01, 1e3))
def test_a_model_that_misfits_is_named_with_its_block_and_never_reassures(block, size):
    fit = {**FITS, block: size, "fits_noise": False}
    text = diagnosis(False, 0.01, 0.009, [], fit=fit, nominal_fit=fit).message()
    assert text.startswith("No candidate cause explains the gap, and the best model found ('friction') does not fit")
    assert f"the {block} residual is {size:.1f} times the noise" in text
    assert "as good as" not in text and "within the noise" not in text


@given(st.booleans())
def test_fitted_values_are_results_only_when_causes_are_named(explained):
    summary = diagnosis(explained, 0.01, 0.009, []).summary()
    fitted = ("parameters", "intervals", "parameter_intervals", "open_sides")
    if explained:
        assert summary["parameters"] == {"friction": 0.3} and summary["best_model"] is None
    else:
        assert all(not summary[key] for key in fitted)
        assert summary["best_model"]["causes"] == ["friction"] and summary["best_model"]["parameters"] == {"friction": 0.3}
        assert "0.3" not in summary["message"]


def test_a_parameter_open_down_to_its_nominal_floor_reads_negligible():
    side = {"cause": "friction", "parameter": "friction coefficient", "side": "below", "fitted": 0.0,
            "negligible": True, "trials_needed": ""}
    text = diagnosis(True, 0.01, 0.002, [side]).message()
    assert "friction coefficient is negligible (at most its upper bound" in text and "cannot bound" not in text


@given(st.lists(st.floats(0.5, 1.5), min_size=2, max_size=12), st.floats(4.0, 50.0), st.integers(0, 12))
def test_a_trial_that_stands_out_is_named_in_the_summary_and_the_message(residuals, outlier, at):
    residuals = list(residuals)
    residuals.insert(at % (len(residuals) + 1), outlier)
    result = diagnosis(True, 0.01, 0.002, [], residuals=residuals)
    summary = result.summary()
    name = f"t{residuals.index(outlier)}"
    assert summary["outlier_trials"] == [name]
    assert [r["residual"] for r in summary["trial_residuals"]] == residuals
    assert f"Trial {name} ({outlier:.1f}) stands out" in summary["message"]
    assert "stands out" not in diagnosis(True, 0.01, 0.002, [], residuals=[r for r in residuals if r != outlier]).message()


def test_differing_timings_are_said_with_the_trials_that_lag_least_and_most():
    """A best model that fits the noise on average but not each trial's timing
    (``timing.timing_test`` refused): the message says so, names the trials of the least and the
    largest lag and the test's numbers, and does not blame the intervals; consistent timings
    add nothing."""
    result = diagnosis(False, 0.1, 0.05, [], nominal_fit={**FITS, "jump": 5.0, "fits_noise": False},
                       residuals=(1.0, 1.2, 1.1))
    result.gain_over_floor = 0.9
    assert "timings differ" not in result.message()
    result.timing = {"shifts": [0.1, 3.0, None], "stds": [0.25, 0.25, None], "statistic": 69.1, "dof": 1,
                     "p_value": 1e-16, "consistent": False}
    message = result.message()
    assert "not each trial's timing" in message and "nominal value" not in message
    assert "0.1 (t0) to 3.0 samples (t1)" in message and "chi-square 69.1 on 1 degrees of freedom" in message
    assert result.summary()["timing"] == result.timing
