"""Hide an effect in a simulated dataset; the diagnosis must find it (sim/diagnosis/pipeline.py)."""

import numpy as np
import pytest
from diagnosis_checks import POSTURES, SPEEDS, check_contract, tolerance

from impactqp.controller.model.validation import BadInputError
from impactqp.sim.causes import PLANT_CAUSE_NAMES, FrictionCause, cause_named, realistic_hidden_effect
from impactqp.sim.diagnosis import EXPLAINED_GAIN, diagnose
from impactqp.sim.diagnosis.pipeline import STEPS
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters


@pytest.mark.parametrize("cause", PLANT_CAUSE_NAMES)
def test_hidden_effect_is_found(tmp_path, cause):
    """One realistic effect hidden (per group for armature and damping): it alone is named and
    every fitted parameter recovered."""
    overrides, tangential = realistic_hidden_effect(cause, np.random.default_rng(sum(map(ord, cause))))
    plant = PlantParameters(**overrides)
    generate_dataset(tmp_path, DatasetRequest(plant=plant, postures=POSTURES, speeds=SPEEDS, tangential=tangential, seed=7))
    steps = []
    result = diagnose(tmp_path, jobs=2, progress=steps.append).summary()
    assert steps == list(STEPS)  # every step announced once, in order
    assert result["causes"] == [cause], result["steps"]
    assert result["cause"] == cause and result["explained"]
    fitted = cause_named(cause)
    truth = fitted.theta_of(overrides)
    assert np.all(np.abs(fitted.theta_of(result["parameters"]) - truth) <= tolerance(fitted, truth))
    assert result["gain_over_floor"] >= EXPLAINED_GAIN and result["fit"]["fits_noise"]
    assert result["gain"] == pytest.approx(1 - result["extended_error"] / result["baseline_error"])
    assert result["trials"] == len(POSTURES) * (len(SPEEDS) + len(tangential)) and result["skipped"] == []
    check_contract(result)


def test_a_single_trial_or_twice_the_same_cause_is_refused(tmp_path):
    """The diagnosis needs two usable trials (bad input) and distinct candidate names (a bug)."""
    generate_dataset(tmp_path / "one", DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    with pytest.raises(BadInputError, match="only 1 usable trial"):
        diagnose(tmp_path / "one")
    generate_dataset(tmp_path / "two", DatasetRequest(postures=["elbow_up"], speeds=[0.1], repeats=2))
    with pytest.raises(ValueError, match="distinct names"):
        diagnose(tmp_path / "two", causes=[FrictionCause(), FrictionCause()])
