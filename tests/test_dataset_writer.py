"""The dataset writer: nothing different overwritten, and no run into a full disk."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from impactqp.controller.measured.dataset import FORCE_COLUMNS, DatasetError, DatasetHeader, TrialEntry
from impactqp.controller.measured.dataset_robot import trial_columns
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.dataset_writer import (
    BYTES_PER_NUMBER,
    SPACE_MARGIN,
    DatasetWriter,
    check_room,
    trial_bytes,
)
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


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MB tmpfs (skipped where mounting is not permitted), unmounted after the test."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


def test_room_is_checked_against_the_margin_on_a_small_disk(small_disk):
    """The folder (still to be made: judged by the disk it would be on) holds the estimate times
    the margin or is refused, in one message naming it, the estimate and the free space; the
    check leaves nothing behind."""
    free = shutil.disk_usage(small_disk).free
    check_room(small_disk / "a" / "b", 0.99 * free / SPACE_MARGIN, "the 3 trials")
    with pytest.raises(DatasetError) as refused:
        check_room(small_disk / "a" / "b", 1.01 * free / SPACE_MARGIN, "the 3 trials")
    message = str(refused.value)
    assert message.startswith(f"{small_disk / 'a' / 'b'}: the 3 trials need about")
    assert f"{1.01 * free / SPACE_MARGIN / 1e6:.1f} MB estimated" in message and f"{free / 1e6:.1f} MB are free" in message
    assert list(small_disk.iterdir()) == []


def test_a_folder_that_cannot_be_written_is_refused(small_disk):
    subprocess.run(["mount", "-o", "remount,ro", str(small_disk)], check=True)
    with pytest.raises(DatasetError, match="cannot write there"):
        check_room(small_disk / "d", 0.0, "the 1 trial")


def test_the_estimate_of_a_trial_holds_its_files(tmp_path, dataset_logs):
    """A trial's files are never larger than the estimate from their rows and the header lines:
    every number written with %.10g, and its separator, fits in BYTES_PER_NUMBER."""
    assert BYTES_PER_NUMBER >= len(f"{-1.234567891e-300:.10g},")
    headers = len(",".join(trial_columns("panda"))) + len(",".join(FORCE_COLUMNS)) + 2
    writer = DatasetWriter(tmp_path, DATASET_HEADER, expected_trials=2)
    for speed, log in dataset_logs.items():
        entry = dataset_entry(f"v{speed}", speed, log)
        writer.add_trial(entry, log)
        written = (tmp_path / entry.file).stat().st_size + (tmp_path / entry.force_file).stat().st_size
        assert written <= trial_bytes("panda", len(log.t), len(log.force_t)) + headers


def _binary(path):
    path.write_bytes(bytes(range(256)) * 20)  # 0x80 and on: no UTF-8 text


def _device(path):
    path.symlink_to("/dev/null")  # a device: read, it would look like an empty file


def _directory(path):
    path.mkdir()


UNREADABLE_TRIAL_FILES = [
    (_binary, "is not a UTF-8 text file"),
    (_device, "is not a regular file (a FIFO, a socket or a device)"),
    (_directory, "is a directory, not a file"),
]
"""Files that cannot be a trial's text, and what the refusal says of each (a FIFO, which a read
would wait on: tests/test_dataset_commands.py, in a process of its own)."""


def _regular_files(directory):
    """The bytes of the regular files of ``directory`` and the kind of every other entry, by name."""
    return {p.name: p.read_bytes() if p.is_file() and not p.is_symlink() else (p.is_symlink(), p.is_dir())
            for p in sorted(directory.iterdir())}


@pytest.mark.parametrize(("make", "reason"), UNREADABLE_TRIAL_FILES[1:])
def test_a_trial_file_of_the_manifest_that_is_not_a_file_is_refused_on_opening(dataset, dataset_logs, make, reason):
    """The manifest names fast.csv: opening the dataset refuses it when it is not a regular file
    (its kind, from one stat: no file is read), naming it, before any trial is added, and the
    dataset is left as it was; a regular file's text is read when a trial is compared with it."""
    (dataset / "fast.csv").unlink()
    make(dataset / "fast.csv")
    before = _regular_files(dataset)
    with pytest.raises(DatasetError) as refused:
        DatasetWriter(dataset, DATASET_HEADER)
    assert str(refused.value) == f"the trial file {dataset / 'fast.csv'} {reason}"
    assert _regular_files(dataset) == before


@pytest.mark.parametrize(("make", "reason"), UNREADABLE_TRIAL_FILES)
def test_a_file_in_the_way_of_a_new_trial_that_is_not_text_is_refused(dataset, dataset_logs, make, reason):
    """A file the manifest does not name, where a new trial would be written: refused naming it,
    nothing written."""
    writer = DatasetWriter(dataset, DATASET_HEADER)
    make(dataset / "new.csv")
    before = _regular_files(dataset)
    with pytest.raises(DatasetError) as refused:
        writer.add_trial(TrialEntry("new", "new.csv", 0.15), dataset_logs[0.15])
    assert str(refused.value) == f"the trial file {dataset / 'new.csv'} {reason}"
    assert _regular_files(dataset) == before and [e.id for e in writer.entries] == ["fast", "slow"]


def test_a_trial_missing_from_its_dataset_is_not_refused_on_opening(dataset, dataset_logs):
    """A trial file the manifest names but that is gone is not read: the writer opens, and the
    trial of that id with its data is refused as other data (nothing to compare it with)."""
    (dataset / "fast.csv").unlink()
    writer = DatasetWriter(dataset, DATASET_HEADER)
    with pytest.raises(DatasetError, match="already exists .* with other data"):
        writer.add_trial(dataset_entry("fast", 0.15, dataset_logs[0.15]), dataset_logs[0.15])
