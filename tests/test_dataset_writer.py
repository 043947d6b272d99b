"""The dataset writer: nothing different overwritten, and no run into a full disk."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from impactqp.controller.measured.dataset import DatasetError, DatasetHeader, TrialEntry
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.dataset_writer import SPACE_MARGIN, DatasetWriter
from impactqp.controller.model.postures import Surface

from conftest import DATASET_HEADER, dataset_entry, file_digests


def test_writer_never_overwrites_a_different_dataset(dataset, dataset_logs):
    other = DatasetHeader(DATASET_HEADER.tool, Surface(np.array([0.7, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])), 1e-3)
    with pytest.raises(DatasetError, match="another header"):
        DatasetWriter(dataset, other)
    writer = DatasetWriter(dataset, DATASET_HEADER)
    before = file_digests(dataset)
    writer.add_trial(dataset_entry("fast", 0.15, dataset_logs[0.15]), dataset_logs[0.15])  # identical: no-op
    with pytest.raises(DatasetError, match="already exists"):
        writer.add_trial(dataset_entry("fast", 0.15, dataset_logs[0.1]), dataset_logs[0.1])
    with pytest.raises(DatasetError, match="already exists"):
        writer.add_trial(TrialEntry("new", "slow.csv", 0.1), dataset_logs[0.15])
    assert file_digests(dataset) == before


def test_a_writer_refuses_to_go_on_when_the_disk_cannot_hold_the_trials_to_come(tmp_path, dataset_logs):
    """The first trial's size times the trials left (and the margin) against the real free space:
    more trials than any disk holds are refused after the first, which stays a valid dataset."""
    log = dataset_logs[0.15]
    first = DatasetWriter(tmp_path / "fits", DATASET_HEADER, expected_trials=2)
    first.add_trial(dataset_entry("fast", 0.15, log), log)
    trial_bytes = sum(p.stat().st_size for p in (tmp_path / "fits").iterdir() if p.name != "dataset.json")
    left = 2 * shutil.disk_usage(tmp_path).free // int(SPACE_MARGIN * trial_bytes) + 10  # twice the free space
    writer = DatasetWriter(tmp_path / "full", DATASET_HEADER, expected_trials=left + 1)
    with pytest.raises(DatasetError, match=f"the {left} left need about"):
        writer.add_trial(dataset_entry("fast", 0.15, log), log)
    assert validate(tmp_path / "full") == {"dataset": [], "fast": []}
