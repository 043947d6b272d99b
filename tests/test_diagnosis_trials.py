"""Loading the trials of a dataset and replaying them (sim/diagnosis/trials.py)."""

import hashlib
from pathlib import Path

import numpy as np
import pytest
from diagnosis_checks import POSTURES, SPEEDS
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.impact import PRE_SAMPLES

from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.model.choice import RobotChoice
from impactqp.sim.causes import PayloadCause
from impactqp.sim.diagnosis import diagnose, load_trials, replay_all
from impactqp.sim.diagnosis.trials import TRACE_LENGTH, impact_trace, trace_at
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters
from impactqp.sim.sensor import delayed


@pytest.mark.parametrize("robot, tool", [("panda", "impact_tip"), ("fr3", "franka_hand")])
def test_replay_in_the_generating_plant_reproduces_the_jumps(tmp_path, robot, tool):
    """A noise-free trial replayed in the plant that made it gives back its own jump: the replay
    simulates the robot and the tool of the manifest."""
    plant = PlantParameters(armature=[0.3] * JOINTS)
    choice = RobotChoice.of(robot, tool)
    request = DatasetRequest(
        plant=plant, postures=["elbow_left"], speeds=[0.15], noise_dq=0.0, noise_tau=0.0, choice=choice
    )
    generate_dataset(tmp_path, request)
    trials, skipped, setting = load_trials(tmp_path)
    assert skipped == [] and setting.choice.same_as(choice)
    (features,) = replay_all(setting, plant, trials)
    np.testing.assert_allclose(features.jump, trials[0].jump, atol=1e-6)
    np.testing.assert_allclose(features.impulse, trials[0].impulse, atol=1e-6)
    np.testing.assert_allclose(features.torque, trials[0].torque, rtol=1e-6, atol=1e-6)  # CSV: 10 digits
    np.testing.assert_allclose(features.trace, trials[0].reference_trace, rtol=1e-6, atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(0, 6))
def test_a_late_sensor_shifts_the_trace_and_leaves_its_pre_impact_mean(seed, late, onset):
    """The trace (``trace_at``) of a signal logged ``late`` samples late is the trace of the
    true one, ``late`` samples later, when the signal is steady before the rise; the impact
    trace puts the velocities' beside the torques'."""
    rng = np.random.default_rng(seed)
    pre = PRE_SAMPLES + 8
    dq = np.tile(rng.normal(size=JOINTS), (pre + TRACE_LENGTH + 10, 1))
    rise = pre + 1 + onset
    dq[rise:] += np.cumsum(rng.uniform(0.0, 0.1, size=(len(dq) - rise, JOINTS)), axis=0)
    trace, late_trace = trace_at(dq, pre), trace_at(delayed(dq, late), pre)
    assert trace.shape == (TRACE_LENGTH, JOINTS)
    np.testing.assert_allclose(late_trace[late:], trace[:-late], atol=1e-12)
    np.testing.assert_allclose(late_trace[: onset + late], 0.0, atol=1e-12)
    both = impact_trace(dq, 2.0 * dq, pre)
    np.testing.assert_array_equal(both, np.hstack([trace, trace_at(2.0 * dq, pre)]))


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
    generate_dataset(tmp_path, DatasetRequest(postures=POSTURES, speeds=SPEEDS, seed=3))
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
