"""Hide an effect in a simulated dataset; the diagnosis must find it (sim/diagnosis/pipeline.py)."""

import json

import numpy as np
import pytest
from diagnosis_checks import POSTURES, SPEEDS, check_contract, tolerance

from conftest import JOINTS
from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.causes import CAUSE_NAMES, PLANT_CAUSE_NAMES, FrictionCause, cause_named, realistic_hidden_effect
from impactqp.sim.diagnosis import EXPLAINED_GAIN, diagnose
from impactqp.sim.diagnosis.pipeline import STEPS
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters


DECOYS = 2
"""Candidates beside the hidden cause in ``test_hidden_effect_is_found``: the next ones of
``CAUSE_NAMES`` (the whole set's accuracy is the bench's ``diagnose.accuracy`` rows)."""


def with_decoys(cause: str) -> list:
    """The cause named ``cause`` and the ``DECOYS`` causes after it in ``CAUSE_NAMES`` (cyclic)."""
    start = CAUSE_NAMES.index(cause)
    return [cause_named(CAUSE_NAMES[(start + k) % len(CAUSE_NAMES)], JOINTS) for k in range(DECOYS + 1)]


@pytest.mark.parametrize("cause", PLANT_CAUSE_NAMES)
def test_hidden_effect_is_found(tmp_path, cause):
    """One realistic effect hidden (per group for armature and damping), diagnosed with two other
    candidates: it alone is named and every fitted parameter recovered."""
    overrides, tangential = realistic_hidden_effect(cause, np.random.default_rng(sum(map(ord, cause))), JOINTS)
    plant = PlantParameters(**overrides)
    generate_dataset(tmp_path, DatasetRequest(plant=plant, postures=POSTURES, speeds=SPEEDS, tangential=tangential, seed=7))
    steps = []
    result = diagnose(tmp_path, causes=with_decoys(cause), jobs=2, progress=steps.append).summary()
    assert steps == list(STEPS)  # every step announced once, in order
    assert result["causes"] == [cause], result["steps"]
    assert result["cause"] == cause and result["explained"]
    fitted = cause_named(cause, JOINTS)
    truth = fitted.theta_of(overrides)
    assert np.all(np.abs(fitted.theta_of(result["parameters"]) - truth) <= tolerance(fitted, truth))
    assert result["gain_over_floor"] >= EXPLAINED_GAIN and result["fit"]["fits_noise"]
    assert result["gain"] == pytest.approx(1 - result["extended_error"] / result["baseline_error"])
    assert result["trials"] == len(POSTURES) * (len(SPEEDS) + len(tangential)) and result["skipped"] == []
    check_contract(result)


def test_a_single_trial_is_replayed_without_selecting_a_cause(tmp_path):
    """One trial (one ``impactqp run`` on a robot): the nominal replay and the predictors, no
    cause, since the selection holds trials out. A trial of the nominal plant fits the nominal
    simulation within the noise; one with an effect hidden does not."""
    generate_dataset(tmp_path / "nominal", DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    result = diagnose(tmp_path / "nominal").summary()
    assert result["trials"] == 1 and result["skipped"] == []
    assert result["causes"] == [] and not result["explained"] and result["parameters"] == {}
    assert result["fit"] == result["nominal_fit"] and result["nominal_fit"]["fits_noise"]
    assert result["extended_error"] == result["baseline_error"] and result["gain"] == 0.0
    assert set(result["predictors"]) == set(METHODS)
    assert result["message"].startswith("One trial") and "matches it within the noise" in result["message"]
    check_contract(result)
    hidden = PlantParameters(sensor_velocity_scale=0.8)  # the encoders read 20 % slow
    generate_dataset(tmp_path / "hidden", DatasetRequest(plant=hidden, postures=["elbow_up"], speeds=[0.1]))
    result = diagnose(tmp_path / "hidden").summary()
    assert not result["nominal_fit"]["fits_noise"] and "does not match it" in result["message"]


def test_no_usable_trial_or_twice_the_same_cause_is_refused(tmp_path):
    """The diagnosis needs a usable trial (bad input) and distinct candidate names (a bug)."""
    generate_dataset(tmp_path / "none", DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    trial = tmp_path / "none" / json.loads((tmp_path / "none" / "dataset.json").read_text())["trials"][0]["file"]
    trial.write_text("".join(trial.read_text().splitlines(keepends=True)[:20]))  # cut before the impact
    with pytest.raises(BadInputError, match="no usable trial"):
        diagnose(tmp_path / "none")
    generate_dataset(tmp_path / "two", DatasetRequest(postures=["elbow_up"], speeds=[0.1], repeats=2))
    with pytest.raises(ValueError, match="distinct names"):
        diagnose(tmp_path / "two", causes=[FrictionCause(), FrictionCause()])


def test_the_identified_panda_is_named_with_intervals_that_hold_or_called_unexplained(tmp_path):
    """A realistic plant out of the causes' exact family: the Panda with Gaz et al.'s identified
    joint friction, different at every joint where the cause fits one value per joint group. The
    diagnosis either names joint friction alone, each group's interval holding the group's mean
    friction, or calls the gap unexplained and names what misfits; it never names a cause that
    is not there."""
    from impactqp.sim.causes import ArmatureCause, JointDampingCause, JointFrictionCause, joint_groups

    plant = PlantParameters.named("identified_panda")
    generate_dataset(tmp_path, DatasetRequest(plant=plant, postures=POSTURES[:2], speeds=SPEEDS, seed=3))
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS), JointDampingCause(JOINTS), JointFrictionCause(JOINTS)]).summary()
    if result["explained"]:
        assert result["causes"] == ["joint_friction"], result["causes"]
        truth = [np.mean([plant.joint_friction[j] for j in group]) for group in joint_groups(JOINTS)]
        for value, p in zip(truth, result["parameter_intervals"]):
            low, high = p["interval"]
            assert (low is None or low <= value) and (high is None or value <= high), (p, value)
    else:
        assert "does not fit the data" in result["message"] and not result["fit"]["fits_noise"], result["message"]


def test_a_trial_whose_log_went_wrong_is_named_not_absorbed(tmp_path):
    """Six trials of the nominal plant; in one, every joint's velocity is logged 2 samples late
    (a log that went wrong in that trial alone). The others fit; that trial is listed with its
    residual, named in ``outlier_trials`` and in the message."""
    from impactqp.sim.causes import ArmatureCause

    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up", "elbow_left"], speeds=[0.1, 0.14, 0.18], seed=5))
    path = tmp_path / "t0002.csv"
    header = path.read_text().splitlines()[0]
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    columns = [header.split(",").index(f"dq{j + 1}") for j in range(JOINTS)]
    table[2:, columns] = table[:-2, columns].copy()
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS)]).summary()
    residuals = {r["id"]: r["residual"] for r in result["trial_residuals"]}
    assert list(residuals) == [f"t{k:04d}" for k in range(6)]
    assert result["outlier_trials"] == ["t0002"], residuals
    assert max(r for k, r in residuals.items() if k != "t0002") < residuals["t0002"] / 2
    assert "Trial t0002 (" in result["message"] and "stands out" in result["message"]
