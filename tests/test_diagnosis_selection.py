"""Forward selection of the causes on held-out error (sim/diagnosis/selection.py)."""

import numpy as np
import pytest
from diagnosis_checks import POSTURES, SPEEDS, check_contract, inside, tolerance
from hypothesis import given
from hypothesis import strategies as st

from impactqp.sim.causes import FrictionCause, PayloadCause, per_group
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.selection import (
    EXPLAINED_GAIN,
    MAX_FOLDS,
    STEP_GAIN,
    fold_of,
    relative_gain,
    selection_step,
)
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters


def test_two_hidden_effects_are_both_named_each_within_its_interval(tmp_path):
    """Armature per group and a payload hidden at once: both are named, refitted jointly, and
    every hidden value (armature per group, payload mass and CoM) lies within its interval."""
    truth = {"armature": per_group((0.6, 0.15)), "payload_mass": 1.0, "payload_com": [0.01, -0.01, -0.06]}
    generate_dataset(tmp_path, DatasetRequest(plant=PlantParameters(**truth), postures=POSTURES, speeds=SPEEDS, seed=7), jobs=2)
    result = diagnose(tmp_path, jobs=2).summary()
    assert sorted(result["causes"]) == ["armature", "payload"], result["steps"]
    check_contract(result)
    for key, value in truth.items():
        pairs = result["intervals"][key]
        values, pairs = (value, pairs) if isinstance(value, list) else ([value], [pairs])
        assert all(inside(v, pair) for v, pair in zip(values, pairs)), key
    payload = PayloadCause()
    theta = payload.theta_of(truth)
    assert np.all(np.abs(payload.theta_of(result["parameters"]) - theta) <= tolerance(payload, theta))
    assert [s["selected"] and s["gain"] >= STEP_GAIN for s in result["steps"][:2]] == [True, True]


def test_nominal_plant_with_noise_is_not_explained(tmp_path):
    generate_dataset(tmp_path, DatasetRequest(postures=POSTURES, speeds=SPEEDS, tangential=[0.05], seed=11))
    result = diagnose(tmp_path, jobs=2).summary()
    assert not result["explained"] and result["causes"] == []
    assert max(c["gain"] for c in result["candidates"]) < EXPLAINED_GAIN
    assert result["steps"] and not result["steps"][0]["selected"]
    assert "No candidate" in result["message"] and "as good as" not in result["message"]
    assert result["nominal_fit"]["fits_noise"] and result["fit"]["fits_noise"]
    check_contract(result)


@given(st.integers(1, 40))
def test_folds_split_the_trials_evenly_into_at_most_max_folds(count):
    folds = fold_of([None] * count)
    sizes = np.bincount(folds)
    assert len(sizes) == min(MAX_FOLDS, count) and sizes.max() - sizes.min() <= 1


@given(st.floats(0.0, 10.0), st.floats(1e-6, 10.0))
def test_a_step_is_selected_when_it_removes_step_gain_of_the_error_before_it(error, previous):
    step = selection_step(FrictionCause(), error, previous)
    assert step["gain"] == pytest.approx(1.0 - error / previous)
    assert step["selected"] == (relative_gain(error, previous) >= STEP_GAIN)
    assert step["cause"] == "friction" and step["heldout_error"] == error


def test_without_a_reference_error_there_is_no_gain():
    assert relative_gain(0.5, 0.0) == 0.0
