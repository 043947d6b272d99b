"""Hide an effect in a simulated dataset; the diagnosis must find it (sim/diagnosis.py)."""

import hashlib
from pathlib import Path

import numpy as np
import pytest

from impactqp.sim.causes import CAUSE_NAMES, FrictionCause, PayloadCause, cause_named, per_group, realistic_hidden_effect
from impactqp.controller.measured.dataset import read_dataset, validate
from impactqp.sim.diagnosis import EXPLAINED_GAIN, STEP_GAIN, diagnose, load_trials, replay_all
from impactqp.sim.generation import generate_dataset
from impactqp.sim.plant import PlantParameters

POSTURES = ["elbow_up", "elbow_left", "elbow_right"]
SPEEDS = [0.1, 0.18]


def inside(value: float, interval) -> bool:
    low, high = interval
    return (low is None or low <= value) and (high is None or value <= high)


def check_contract(result: dict) -> None:
    """The JSON contract of ``diagnose --json``: intervals per parameter key, steps, causes."""
    assert set(result["intervals"]) == set(result["parameters"])
    for key, value in result["parameters"].items():
        interval = result["intervals"][key]
        if isinstance(value, list):
            assert len(interval) == len(value) and all(len(pair) == 2 for pair in interval)
            assert all(inside(v, pair) for v, pair in zip(value, interval))
        else:
            assert len(interval) == 2 and inside(value, interval)
    assert [s["cause"] for s in result["steps"] if s["selected"]] == result["causes"]
    assert result["cause"] == (result["causes"][0] if result["causes"] else result["cause"])
    PlantParameters.from_dict(result["parameters"])  # usable with --plant


def tolerance(cause, truth: np.ndarray) -> np.ndarray:
    """20 % of each value, at least 2 % of its bounds' span (a CoM coordinate near 0)."""
    return 0.2 * np.maximum(np.abs(truth), 0.1 * (np.array(cause.upper) - np.array(cause.lower)))


@pytest.mark.parametrize("cause", CAUSE_NAMES)
def test_hidden_effect_is_found(tmp_path, cause):
    """One realistic effect hidden (per group for armature and damping): it alone is named and
    every fitted parameter recovered."""
    overrides, tangential = realistic_hidden_effect(cause, np.random.default_rng(sum(map(ord, cause))))
    plant = PlantParameters(**overrides)
    generate_dataset(tmp_path, plant=plant, postures=POSTURES, speeds=SPEEDS, tangential=tangential, seed=7)
    result = diagnose(tmp_path, jobs=2).summary()
    assert result["causes"] == [cause], result["steps"]
    assert result["cause"] == cause and result["explained"]
    fitted = cause_named(cause)
    truth = fitted.theta_of(overrides)
    assert np.all(np.abs(fitted.theta_of(result["parameters"]) - truth) <= tolerance(fitted, truth))
    assert result["gain"] >= EXPLAINED_GAIN
    assert result["gain"] == pytest.approx(1 - result["extended_error"] / result["baseline_error"])
    assert result["trials"] == len(POSTURES) * (len(SPEEDS) + len(tangential)) and result["skipped"] == []
    check_contract(result)


def test_two_hidden_effects_are_both_named_each_within_its_interval(tmp_path):
    """Armature per group and a payload hidden at once: both are named, refitted jointly, and
    every hidden value (armature per group, payload mass and CoM) lies within its interval."""
    truth = {"armature": per_group((0.6, 0.15)), "payload_mass": 1.0, "payload_com": [0.01, -0.01, -0.06]}
    generate_dataset(tmp_path, plant=PlantParameters(**truth), postures=POSTURES, speeds=SPEEDS, seed=7, jobs=2)
    result = diagnose(tmp_path, jobs=2).summary()
    assert result["causes"] == ["armature", "payload"], result["steps"]
    check_contract(result)
    for key, value in truth.items():
        pairs = result["intervals"][key]
        values, pairs = (value, pairs) if isinstance(value, list) else ([value], [pairs])
        assert all(inside(v, pair) for v, pair in zip(values, pairs)), key
    payload = PayloadCause()
    theta = payload.theta_of(truth)
    assert np.all(np.abs(payload.theta_of(result["parameters"]) - theta) <= tolerance(payload, theta))
    assert [s["selected"] and s["gain"] >= STEP_GAIN for s in result["steps"][:2]] == [True, True]


def test_impacts_that_only_stick_leave_friction_open_above(tmp_path):
    """mu = 0.6 and a tangential speed of 0.03 m/s at v_n = 0.12 m/s: every impact sticks, so the
    data bound mu from below only; the message says so and names the trials that would settle it."""
    generate_dataset(tmp_path, plant=PlantParameters(friction=0.6), postures=POSTURES[:2], speeds=[0.12],
                     tangential=[0.03], seed=3)
    result = diagnose(tmp_path, causes=[FrictionCause()]).summary()
    assert result["causes"] == ["friction"]
    low, high = result["intervals"]["friction"]
    assert high is None and low is not None and low <= 0.6
    assert [(o["parameter"], o["side"]) for o in result["open_sides"]] == [("friction coefficient", "above")]
    assert "cannot bound friction coefficient above" in result["message"]
    assert "tangential speeds of several mu times the normal speed" in result["message"]
    assert "normal speeds of 0.12 m/s" in result["message"]  # the dataset's own, not a constant


def test_nominal_plant_with_noise_is_not_explained(tmp_path):
    generate_dataset(tmp_path, postures=POSTURES, speeds=SPEEDS, tangential=[0.05], seed=11)
    result = diagnose(tmp_path, jobs=2).summary()
    assert not result["explained"] and result["causes"] == []
    assert max(c["gain"] for c in result["candidates"]) < EXPLAINED_GAIN
    assert result["steps"] and not result["steps"][0]["selected"]
    assert "No candidate" in result["message"]
    check_contract(result)


def test_replay_in_the_generating_plant_reproduces_the_jumps(tmp_path):
    """A noise-free trial replayed in the plant that made it gives back its own jump."""
    plant = PlantParameters(armature=[0.3] * 7)
    generate_dataset(tmp_path, plant=plant, postures=["elbow_left"], speeds=[0.15], noise_dq=0.0, noise_tau=0.0)
    trials, skipped, surface = load_trials(tmp_path)
    assert skipped == []
    (features,) = replay_all(surface, plant, trials)
    np.testing.assert_allclose(features.jump, trials[0].jump, atol=1e-6)
    np.testing.assert_allclose(features.impulse, trials[0].impulse, atol=1e-6)
    np.testing.assert_allclose(features.torque, trials[0].torque, rtol=1e-6, atol=1e-6)  # CSV: 10 digits


def digest(directory: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.iterdir())}


def corrupt(directory: Path) -> dict[str, str]:
    """Damage four trials in four ways; return the expected words of each problem."""
    entries = {e.entry.id: e.entry for e in read_dataset(directory).trials}
    ids = sorted(entries)
    truncated = directory / entries[ids[0]].file
    lines = truncated.read_text().splitlines()
    truncated.write_text("\n".join(lines[:20]) + "\n")
    nan_file = directory / entries[ids[1]].file
    lines = nan_file.read_text().splitlines()
    cells = lines[40].split(",")
    cells[9] = "nan"
    lines[40] = ",".join(cells)
    nan_file.write_text("\n".join(lines) + "\n")
    column_file = directory / entries[ids[2]].file
    lines = column_file.read_text().splitlines()
    column_file.write_text("\n".join(",".join(line.split(",")[:-1]) for line in lines) + "\n")
    (directory / entries[ids[3]].force_file).unlink()
    return {ids[0]: "samples", ids[1]: "NaN", ids[2]: "dq_cmd7", ids[3]: "force"}


def test_corrupted_trials_are_reported_and_skipped(tmp_path):
    generate_dataset(tmp_path, postures=POSTURES, speeds=SPEEDS, seed=3)
    expected = corrupt(tmp_path)
    before = digest(tmp_path)
    problems = validate(tmp_path)
    for trial_id, word in expected.items():
        assert any(word in p for p in problems[trial_id]), problems[trial_id]
    result = diagnose(tmp_path, causes=[PayloadCause()]).summary()
    assert {s["id"] for s in result["skipped"]} == set(expected)
    for s in result["skipped"]:
        assert expected[s["id"]] in s["reason"]
    assert result["trials"] == len(POSTURES) * len(SPEEDS) - len(expected)
    assert digest(tmp_path) == before
