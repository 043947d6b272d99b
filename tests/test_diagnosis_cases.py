"""Held-out cases of issue 32, end to end: a dataset generated with an effect, diagnosed, and
what the diagnosis may say of it (sim/generation.py's effects, sim/diagnosis/ as a whole)."""

import numpy as np

from conftest import JOINTS
from impactqp.controller.measured.dataset import read_dataset
from impactqp.sim.causes import DelayCause, JointDampingCause, VelocityFilterCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset

DELAYED = {"postures": ["elbow_up", "elbow_left"], "speeds": [0.1, 0.18], "repeats": 2, "seed": 6}


def drawn_delays(tmp_path) -> dict[str, int]:
    """Each trial's delay of dq in the datasets of ``DELAYED`` with ``velocity_delays`` = 4, read
    exactly from two noise-free twins (the delay is drawn after the noise, whatever its std)."""
    twins = {}
    for name, delays in (("on_time", 0), ("late", 4)):
        generate_dataset(tmp_path / name, DatasetRequest(velocity_delays=delays, noise_dq=0.0, **DELAYED), jobs=2)
        twins[name] = read_dataset(tmp_path / name).trials
    found = {}
    for on_time, late in zip(twins["on_time"], twins["late"]):
        dq = on_time.log.dq
        found[late.entry.id] = next(d for d in range(5) if np.array_equal(
            late.log.dq, np.vstack([np.repeat(dq[:1], d, 0), dq[: len(dq) - d]])))
    return found


def test_a_per_trial_variable_delay_is_called_unexplained_with_its_misfit_named(tmp_path):
    """Each trial's dq logged 0-4 samples late, drawn per trial: no candidate holds it (a sensor
    delay is one for the whole dataset, on dq and tau alike; a filter or a damping is one for
    every trial). Among the causes that mimic a late velocity best, none may be named: the
    diagnosis says the gap is not explained, names the misfit and saves no plant; a trial it
    names as an outlier is one whose dq was delayed."""
    delays = drawn_delays(tmp_path)
    assert len(set(delays.values())) > 1, delays  # the delay differs between trials
    generate_dataset(tmp_path / "data", DatasetRequest(velocity_delays=4, **DELAYED), jobs=2)
    candidates = [DelayCause(), VelocityFilterCause(), JointDampingCause(JOINTS)]
    result = diagnose(tmp_path / "data", causes=candidates, jobs=2).summary()
    assert not result["explained"] and result["causes"] == [] and result["parameters"] == {}, result["message"]
    assert not result["fit"]["fits_noise"]
    assert "does not fit the data" in result["message"] and "times the noise" in result["message"], result["message"]
    assert all(delays[trial] > 0 for trial in result["outlier_trials"]), (result["outlier_trials"], delays)

