"""Simulated datasets in the measured-data format (sim/generation.py)."""

import json

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.sim.generation import START_DISTANCE, DatasetRequest, generate_dataset, tangential_direction, trial_specs
from impactqp.sim.plant import PlantParameters


def test_trial_grid_and_tangential_direction():
    n = np.array([-1.0, 0.0, 0.0])
    specs = trial_specs(["elbow_up", "elbow_left"], [0.1, 0.2], [0.05], 3, n, seed=1)
    assert len(specs) == (2 * 2 + 2 * 1) * 3
    assert len({s.id for s in specs}) == len(specs) and len({s.seed for s in specs}) == len(specs)
    tangential = [s.spec for s in specs if np.any(s.spec.tangential_velocity)]
    assert all(s.normal_speed == 0.12 for s in tangential)
    np.testing.assert_allclose(tangential[0].tangential_velocity, [0.0, 0.05, 0.0], atol=1e-15)
    for normal in (n, np.array([0.0, 0.0, 1.0]), np.array([0.3, -0.4, 0.866])):
        normal = normal / np.linalg.norm(normal)
        t = tangential_direction(normal)
        assert abs(t @ normal) < 1e-12 and np.linalg.norm(t) == pytest.approx(1.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [({"postures": ["nowhere"]}, "unknown posture"), ({"speeds": [0.0]}, r"\(0, 3\] m/s"), ({"repeats": 0}, "repeats")],
)
def test_bad_requests_are_rejected(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        generate_dataset(tmp_path, DatasetRequest(**{"postures": ["elbow_up"], "speeds": [0.1], **kwargs}))


def test_dataset_is_valid_and_holds_no_plant_parameters(tmp_path):
    plant = PlantParameters(payload_mass=0.7, armature=[0.2] * JOINTS, friction=0.5)
    request = DatasetRequest(plant=plant, postures=["elbow_up"], speeds=[0.1, 0.15], repeats=2)
    entries = generate_dataset(tmp_path, request, jobs=2)
    assert len(entries) == 4
    assert all(not v for v in validate(tmp_path).values())
    manifest = (tmp_path / "dataset.json").read_text()
    for key in set(plant.to_dict()) - {"friction"}:
        assert key not in manifest
    # the surface's nominal friction is recorded, never the plant's true one
    assert json.loads(manifest)["surface"]["friction"] == 0.1123
    dataset = read_dataset(tmp_path)
    for trial in dataset.trials:
        log = trial.log
        assert log.has_force
        # the trial starts START_DISTANCE (+-1 mm) away and runs 50 ms past the first contact
        touching = np.flatnonzero(np.linalg.norm(log.force, axis=1) > 0)
        assert log.force_t[-1] - log.force_t[touching[0]] == pytest.approx(0.05, abs=2e-3)
        speed = trial.entry.reference_normal_speed
        assert log.force_t[touching[0]] == pytest.approx(START_DISTANCE / speed, rel=0.1)


def test_noise_is_what_was_asked_for(tmp_path):
    """Same seed with and without noise: the difference has the requested standard deviations."""
    common = {"postures": ["elbow_left"], "speeds": [0.12], "seed": 4}
    generate_dataset(tmp_path / "clean", DatasetRequest(noise_dq=0.0, noise_tau=0.0, **common))
    generate_dataset(tmp_path / "noisy", DatasetRequest(noise_dq=0.0042, noise_tau=0.05, **common))
    clean = read_dataset(tmp_path / "clean").trials[0].log
    noisy = read_dataset(tmp_path / "noisy").trials[0].log
    assert np.std(noisy.dq - clean.dq) == pytest.approx(0.0042, rel=0.1)
    assert np.std(noisy.tau - clean.tau) == pytest.approx(0.05, rel=0.1)
    np.testing.assert_array_equal(noisy.q, clean.q)


def test_generation_is_reproducible_on_any_number_of_jobs_and_never_overwrites(tmp_path):
    common = {"postures": ["elbow_up"], "speeds": [0.1, 0.12], "seed": 9}
    generate_dataset(tmp_path / "a", DatasetRequest(**common))
    generate_dataset(tmp_path / "b", DatasetRequest(**common), jobs=2)
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "b").iterdir()) and "t0001.csv" in names
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    before = (tmp_path / "a" / "t0000.csv").read_bytes()
    with pytest.raises(ValueError):
        generate_dataset(tmp_path / "a", DatasetRequest(**{**common, "seed": 10}))
    assert (tmp_path / "a" / "t0000.csv").read_bytes() == before
    assert json.loads((tmp_path / "a" / "dataset.json").read_text())["trials"][0]["id"] == "t0000"
