"""The diagnosis's result: its JSON summary and its message (sim/diagnosis/result.py)."""

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
              nominal_fit: dict = FITS) -> Diagnosis:
    trials = [synthetic_trial(np.random.default_rng(k)) for k in range(2)]
    causes = ["friction"] if explained else []
    parameter = {"cause": "friction", "parameter": "friction coefficient", "value": 0.3, "interval": [0.2, None]}
    return Diagnosis(
        trials=trials, skipped=[], nominal_jumps=np.zeros((2, JOINTS)), extended_jumps=np.zeros((2, JOINTS)),
        baseline_errors=np.array([baseline, baseline]), candidates=[], cause="friction", explained=explained,
        parameters={"friction": 0.3}, predictors={}, predictors_measured_impulse={}, predictions={}, analysis={},
        causes=causes, steps=[], intervals={"friction": [0.2, None]}, parameter_intervals=[parameter],
        open_sides=open_sides, extended_error=extended, extended_plant=PlantParameters(), surface=DEFAULT_WALL,
        choice=DEFAULT_CHOICE,
        gain_over_floor=0.1, fit=fit, nominal_fit=nominal_fit,
    )


@given(st.booleans(), st.floats(1e-3, 1.0), st.floats(0.0, 1.0))
def test_the_summary_has_every_key_and_its_gain_is_one_minus_the_error_ratio(explained, baseline, extended):
    summary = diagnosis(explained, baseline, extended, []).summary()
    assert set(summary) == SUMMARY_KEYS
    assert summary["gain"] == pytest.approx(1.0 - extended / baseline)
    assert summary["trials"] == 2 and summary["causes"] == (["friction"] if explained else [])


def test_the_message_names_the_causes_their_intervals_and_what_is_open():
    side = {"cause": "friction", "parameter": "friction coefficient", "side": "above", "fitted": 0.3,
            "trials_needed": "faster sliding trials"}
    text = diagnosis(True, 0.01, 0.002, [side]).message()
    assert text.startswith("The gap between the simulation and the measurements is explained by 'friction'")
    assert "friction coefficient: 0.3, 95 % interval at least 0.2 (open above)." in text
    assert "cannot bound friction coefficient above: faster sliding trials." in text
    assert "within the noise (jump 1.1, torque 0.9, impulse 0.5, duration 0.4 noise units)" in text
    misfit = {**FITS, "fits_noise": False}
    text = diagnosis(False, 0.01, 0.009, [side], nominal_fit=misfit).message()
    assert text.startswith("No candidate cause explains the gap: the best one, 'friction'")
    assert f"threshold {100 * EXPLAINED_GAIN:.0f} %" in text and "cannot bound" not in text
    text = diagnosis(False, 0.01, 0.009, [side]).message()
    assert text.startswith("No candidate cause is needed: the nominal simulation already matches the data")


@given(st.sampled_from(["jump", "torque", "impulse", "duration"]), st.floats(FIT_LIMIT * 1.01, 1e3))
def test_a_model_that_misfits_is_named_with_its_block_and_never_reassures(block, size):
    fit = {**FITS, block: size, "fits_noise": False}
    text = diagnosis(False, 0.01, 0.009, [], fit=fit, nominal_fit=fit).message()
    assert text.startswith("No candidate cause explains the gap, and the best model found ('friction') does not fit")
    assert f"the {block} residual is {size:.1f} times the noise" in text
    assert "as good as" not in text and "within the noise" not in text
