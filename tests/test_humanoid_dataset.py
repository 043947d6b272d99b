"""Simulated G1 trials as a dataset (sim/humanoid_dataset.py): the round trip, and the impact
extraction of docs/dataset.md against what the trial itself measured."""

import json

import numpy as np
import pytest

from impactqp.controller.measured.dataset import DatasetError, read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.impact import DEFAULT_FORCE_THRESHOLD, measure_impact
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.sim.humanoid_dataset import dataset_log, open_dataset, trial_entry, write_trials
from impactqp.sim.humanoid_trial import CONTROL_PERIOD, run_impact_trial

from conftest import G1_HEADER, g1_model, file_digests


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
        assert len(log) == len(trial.q_log) and log.q.shape[1] == robot.n_joints
        assert log.base.shape == (len(log), robot.base_nq + robot.base_nv)
        np.testing.assert_array_equal(np.column_stack([log.base[:, :robot.base_nq], log.q]), trial.q_log)
        np.testing.assert_allclose(log.t, np.arange(len(log)) * CONTROL_PERIOD, rtol=0, atol=1e-12)
        substeps = len(log.force_t) // len(log)
        touching = np.any(log.force.reshape(len(log), substeps, 3) != 0.0, axis=(1, 2))
        assert int(np.argmax(touching)) == trial.contact_index
        # the wall impulse of the first contact is the physics steps' forces summed
        first, last = trial.contact_index, trial.contact_index + int(round(trial.duration / CONTROL_PERIOD))
        step = log.force_t[1] - log.force_t[0]
        np.testing.assert_allclose(log.force[first * substeps:last * substeps].sum(axis=0) * step, trial.impulse,
                                   rtol=1e-12, atol=1e-12)


def test_written_trials_read_back_as_logged(written, trials):
    data = read_dataset(written)
    assert data.header.to_dict() == G1_HEADER.to_dict()
    assert [t.entry for t in data.trials] == [trial_entry(t) for t in trials]
    for read, trial in zip(data.trials, trials):
        expected = dataset_log(trial)
        for name in ("t", "q", "dq", "tau", "dq_cmd", "base", "force_t", "force"):
            np.testing.assert_allclose(getattr(read.log, name), getattr(expected, name), rtol=1e-9, atol=1e-12)
        # the dataset's world frame is the simulation's moved onto the wall: only the base's x differs
        np.testing.assert_allclose(read.log.base[:, 0] + trial.wall_x, trial.log.base[:, 0], rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(expected.base[:, 1:], trial.log.base[:, 1:])
    assert validate(written) == {"dataset": [], **{trial_entry(t).id: [] for t in trials}}


def test_the_extraction_agrees_with_the_trial_where_their_definitions_coincide(written, trials):
    """Both take the state before the impact at the last control sample before the contact, and
    the impulse over the first contact; the trial reads the jump right after its first contact
    (control steps with a wall force), the extraction at the sample of largest velocity change in
    its window [-5, +20] ms, averaged over 3 samples (docs/dataset.md)."""
    for read, trial in zip(read_dataset(written).trials, trials):
        log = read.log
        impact = measure_impact(log)
        k = trial.contact_index
        start = int(np.argmax(np.linalg.norm(log.force, axis=1) > DEFAULT_FORCE_THRESHOLD))
        assert impact.method == "force" and impact.t_contact_start == pytest.approx(log.force_t[start], abs=1e-12)
        assert impact.pre_index == int(np.searchsorted(log.t, log.force_t[start], side="right")) - 1
        # the wall force passes 1 N within the first contact's control period: the same sample
        assert impact.pre_index == k
        np.testing.assert_allclose(impact.q_pre, trial.q_log[k][g1_model().base_nq:], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(impact.dq_pre, log.dq[k - 2:k + 1].mean(axis=0), rtol=1e-12, atol=1e-12)
        # the trial's jump is the velocity after its first contact minus the one before, over the joints
        post = k + int(round(trial.duration / CONTROL_PERIOD))
        np.testing.assert_allclose(log.dq[post] - log.dq[k], trial.measured_jump[g1_model().base_nv:], rtol=1e-8, atol=1e-8)
        # the extraction's sample of largest change is at least as far from dq- as the trial's
        first, last = impact.window
        assert first <= post <= last
        change = np.linalg.norm(log.dq - impact.dq_pre, axis=1)
        assert change[impact.post_index] >= change[post]
        # one impulse: the trapezoid over the force samples against the sum of the physics steps
        np.testing.assert_allclose(impact.impulse, trial.impulse, rtol=1e-2)
        assert abs(read.entry.impact_time - impact.t_contact_start) <= CONTROL_PERIOD


def test_the_writer_adds_nothing_twice_and_overwrites_nothing(written, trials):
    before = file_digests(written)
    write_trials(open_dataset(written), trials[:1])  # the same trial again: nothing changes
    assert file_digests(written) == before
    manifest = json.loads((written / "dataset.json").read_text())
    assert [t["id"] for t in manifest["trials"]] == [trial_entry(t).id for t in trials]
    changed = trials[0].__class__(**{**trials[0].__dict__, "log": trials[1].log})
    with pytest.raises(DatasetError, match="already exists"):
        write_trials(open_dataset(written), [changed])
    assert file_digests(written) == before
