"""Simulated datasets in the measured-data format (sim/generation.py): the arm's generated datasets;
the standing G1's trials as a dataset, the round trip, and the impact extraction of docs/dataset.md
against what the trial itself measured."""

import json

import numpy as np
import pytest

from conftest import G1_HEADER, JOINTS, file_digests, g1_model
from impactqp.controller.measured.dataset import DatasetError, read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.impact import DEFAULT_FORCE_THRESHOLD, measure_impact
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.measured.dataset_writer import SPACE_MARGIN, trial_bytes
from impactqp.sim.generation import (
    START_DISTANCE,
    DatasetRequest,
    dataset_bytes,
    generate_dataset,
    open_dataset,
    tangential_direction,
    trial_specs,
    write_trials,
)
from impactqp.sim.runner import DEFAULT_CONTROL_PERIOD, run_impact_trial
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
    [({"postures": ["nowhere"]}, "unknown posture"), ({"speeds": [0.0]}, r"\[0.001, 3\] m/s"), ({"repeats": 0}, "repeats"),
     ({"velocity_delays": -1}, "per-trial delay"), ({"velocity_delays": 1.5}, "per-trial delay")],
)
def test_bad_requests_are_rejected(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        generate_dataset(tmp_path, DatasetRequest(**{"postures": ["elbow_up"], "speeds": [0.1], **kwargs}))


def test_a_dataset_beyond_the_free_space_is_refused_before_the_first_trial(tmp_path, monkeypatch):
    """The estimate (every trial's nominal duration in samples, times the columns and the bytes of
    a number) against the free space, read at its one place: refused before any trial runs, with
    nothing written, in one message with the estimate and the free space; half the estimate is
    refused, twice the estimate with the margin is accepted."""
    import shutil

    import impactqp.controller.measured.dataset_writer as dataset_writer

    request = DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.15])
    specs = trial_specs(["elbow_up"], [0.1, 0.15], [], 1, np.array([-1.0, 0.0, 0.0]), 0, request.choice)
    estimate = dataset_bytes([planned.spec for planned in specs], request.choice.robot)
    assert estimate > 2 * trial_bytes("panda", round(START_DISTANCE / 0.15 / DEFAULT_CONTROL_PERIOD), 0)
    for free, accepted in ((estimate / 2, False), (2 * SPACE_MARGIN * estimate, True)):
        usage = shutil.disk_usage(tmp_path)._replace(free=int(free))
        monkeypatch.setattr(dataset_writer.shutil, "disk_usage", lambda path, usage=usage: usage)
        if accepted:
            assert len(generate_dataset(tmp_path / "fits", request)) == 2
            continue
        monkeypatch.setattr("impactqp.sim.generation.simulate_trial", lambda task: pytest.fail("a trial ran"))
        with pytest.raises(DatasetError, match=f"the 2 trials need about .*{estimate / 1e6:.1f} MB estimated"):
            generate_dataset(tmp_path / "full", request)
        assert not (tmp_path / "full").exists()
        monkeypatch.undo()


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


def test_a_quantising_sensor_logs_multiples_of_its_step_and_the_manifest_declares_it(tmp_path):
    """A plant whose encoder quantises dq (``sensor_velocity_step``): every logged dq is a
    multiple of its joint's step, and the manifest declares the steps (``encoder_step``); the
    dataset is valid."""
    steps = (0.004,) * (JOINTS - 1) + (0.0,)
    generate_dataset(tmp_path, DatasetRequest(plant=PlantParameters(sensor_velocity_step=steps),
                                              postures=["elbow_up"], speeds=[0.1]))
    data = read_dataset(tmp_path)
    assert data.header.encoder_step == steps
    dq = data.trials[0].log.dq
    np.testing.assert_allclose(dq[:, :-1] / 0.004, np.round(dq[:, :-1] / 0.004), atol=1e-6)
    assert len(np.unique(dq[:, -1])) > len(dq) // 2  # the last joint's step is 0: not quantised
    assert all(not v for v in validate(tmp_path).values())


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


def test_a_per_trial_variable_delay_logs_each_trials_dq_a_whole_number_of_samples_late(tmp_path):
    """Same seed with and without ``velocity_delays`` = 4 (no dq noise, so the delay is read
    exactly): each trial's dq is the undelayed one read d samples late, its first sample held
    before, d in 0..4 drawn per trial and not the same for every trial; q and tau (its noise the
    same draw) are the undelayed ones."""
    common = {"postures": ["elbow_up", "elbow_left"], "speeds": [0.1, 0.18], "repeats": 2, "seed": 6, "noise_dq": 0.0}
    generate_dataset(tmp_path / "on_time", DatasetRequest(**common), jobs=2)
    generate_dataset(tmp_path / "late", DatasetRequest(velocity_delays=4, **common), jobs=2)
    delays = []
    for on_time, late in zip(read_dataset(tmp_path / "on_time").trials, read_dataset(tmp_path / "late").trials):
        np.testing.assert_array_equal(late.log.q, on_time.log.q)
        np.testing.assert_array_equal(late.log.tau, on_time.log.tau)
        dq = on_time.log.dq
        shifted = [d for d in range(5) if np.array_equal(late.log.dq, np.vstack([np.repeat(dq[:1], d, 0), dq[: len(dq) - d]]))]
        assert len(shifted) == 1, shifted
        delays += shifted
    assert len(set(delays)) > 1, delays


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


@pytest.fixture(scope="module")
def trials():
    robot = RobotModel("g1")
    return [run_impact_trial(robot, STANCES[stance], 0.3) for stance in ("parallel", "close")]


@pytest.fixture()
def written(tmp_path, trials):
    write_trials(open_dataset(tmp_path), trials)
    return tmp_path


def test_the_log_is_what_the_trial_ran(trials):
    """The log's rows are the trial's control steps: its configurations and the first contact at
    the first control period with a wall force."""
    for trial in trials:
        log = trial.log
        robot = g1_model()
        assert len(log) == len(trial.held.q_log) and log.q.shape[1] == robot.n_joints
        assert log.base.shape == (len(log), robot.base_nq + robot.base_nv)
        np.testing.assert_array_equal(np.column_stack([log.base[:, :robot.base_nq], log.q]), trial.held.q_log)
        np.testing.assert_allclose(log.t, np.arange(len(log)) * DEFAULT_CONTROL_PERIOD, rtol=0, atol=1e-12)
        substeps = len(log.force_t) // len(log)
        touching = np.any(log.force.reshape(len(log), substeps, 3) != 0.0, axis=(1, 2))
        assert int(np.argmax(touching)) == trial.impact.pre_index
        # the wall impulse of the first contact is the physics steps' forces summed
        first, last = trial.impact.pre_index, trial.impact.pre_index + int(round(trial.impact.duration / DEFAULT_CONTROL_PERIOD))
        step = log.force_t[1] - log.force_t[0]
        np.testing.assert_allclose(log.force[first * substeps:last * substeps].sum(axis=0) * step, trial.impact.impulse,
                                   rtol=1e-12, atol=1e-12)


def test_written_trials_read_back_as_logged(written, trials):
    data = read_dataset(written)
    assert data.header.to_dict() == G1_HEADER.to_dict()
    assert [t.entry for t in data.trials] == [t.dataset_trial()[0] for t in trials]
    for read, trial in zip(data.trials, trials):
        expected = trial.dataset_trial()[1]
        for name in ("t", "q", "dq", "tau", "dq_cmd", "base", "force_t", "force"):
            np.testing.assert_allclose(getattr(read.log, name), getattr(expected, name), rtol=1e-9, atol=1e-12)
        # the dataset's world frame is the simulation's moved onto the wall: only the base's x differs
        np.testing.assert_allclose(read.log.base[:, 0] + trial.held.wall_x, trial.log.base[:, 0], rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(expected.base[:, 1:], trial.log.base[:, 1:])
    assert validate(written) == {"dataset": [], **{t.trial_id: [] for t in trials}}


def test_the_extraction_agrees_with_the_trial_where_their_definitions_coincide(written, trials):
    """Both take the state before the impact at the last control sample before the contact, and
    the impulse over the first contact; the trial reads the jump right after its first contact
    (control steps with a wall force), the extraction at the sample of largest velocity change in
    its window [-5, +20] ms, averaged over 3 samples (docs/dataset.md)."""
    for read, trial in zip(read_dataset(written).trials, trials):
        log = read.log
        impact = measure_impact(log)
        k = trial.impact.pre_index
        start = int(np.argmax(np.linalg.norm(log.force, axis=1) > DEFAULT_FORCE_THRESHOLD))
        assert impact.method == "force" and impact.t_contact_start == pytest.approx(log.force_t[start], abs=1e-12)
        assert impact.pre_index == int(np.searchsorted(log.t, log.force_t[start], side="right")) - 1
        # the wall force passes 1 N within the first contact's control period: the same sample
        assert impact.pre_index == k
        np.testing.assert_allclose(impact.q_pre, trial.held.q_log[k][g1_model().base_nq:], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(impact.dq_pre, log.dq[k - 2:k + 1].mean(axis=0), rtol=1e-12, atol=1e-12)
        # the trial's jump is the velocity after its first contact minus the one before, over the joints
        post = k + int(round(trial.impact.duration / DEFAULT_CONTROL_PERIOD))
        np.testing.assert_allclose(log.dq[post] - log.dq[k], trial.measured_jump[g1_model().base_nv:], rtol=1e-8, atol=1e-8)
        # the extraction's sample of largest change is at least as far from dq- as the trial's
        first, last = impact.window
        assert first <= post <= last
        change = np.linalg.norm(log.dq - impact.dq_pre, axis=1)
        assert change[impact.post_index] >= change[post]
        # one impulse: the trapezoid over the force samples against the sum of the physics steps
        np.testing.assert_allclose(impact.impulse, trial.impact.impulse, rtol=1e-2)
        assert abs(read.entry.impact_time - impact.t_contact_start) <= DEFAULT_CONTROL_PERIOD


def test_the_writer_adds_nothing_twice_and_overwrites_nothing(written, trials):
    before = file_digests(written)
    write_trials(open_dataset(written), trials[:1])  # the same trial again: nothing changes
    assert file_digests(written) == before
    manifest = json.loads((written / "dataset.json").read_text())
    assert [t["id"] for t in manifest["trials"]] == [t.trial_id for t in trials]
    changed = trials[0].__class__(**{**trials[0].__dict__, "log": trials[1].log})
    with pytest.raises(DatasetError, match="already exists"):
        write_trials(open_dataset(written), [changed])
    assert file_digests(written) == before
