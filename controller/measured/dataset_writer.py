"""Writing an impact dataset (the format: ``dataset``): trials are added one by one, each file
atomically, the manifest rewritten after each; nothing different is ever overwritten.

An existing file the writer compares a trial with is read by ``files.read_text``: one that is
not a regular UTF-8 text file of at most ``files.MAX_FILE_BYTES`` (a directory, a FIFO, a device,
binary data) is refused naming it, never opened when it could block or have no end."""

from __future__ import annotations

import io
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

from impactqp.controller.model.files import read_text, regular_file
from impactqp.controller.model.robot_description import robot_description

from .atomic import write_text_atomic
from .dataset import (
    FORCE_COLUMNS,
    MANIFEST,
    DatasetError,
    DatasetHeader,
    TrialEntry,
    load_manifest,
    parse_entry,
)
from .dataset_robot import base_columns, trial_columns
from .trial_log import TrialLog

SPACE_MARGIN = 1.5
"""The free space asked for, in units of the estimated output: before the work, of its estimate
(``trial_bytes``); after the first trial, of the trials still to come at the size of the first
one (a slower trial logs more samples)."""
BYTES_PER_NUMBER = 18
"""Bytes of one number in a trial's CSV files: ``%.10g`` writes at most 17 characters (a sign,
ten digits, a point, an exponent ``e-XX``), then a separator."""


def trial_bytes(robot, samples: int, force_samples: int) -> int:
    """The estimated size of one trial's files: ``samples`` rows of the trial file's columns
    (``dataset_robot.trial_columns`` of ``robot``) and ``force_samples`` rows of the force file's,
    ``BYTES_PER_NUMBER`` each."""
    return BYTES_PER_NUMBER * (samples * len(trial_columns(robot)) + force_samples * len(FORCE_COLUMNS))


def check_room(folder: str | Path, estimate: float, what: str) -> None:
    """Refuse (DatasetError, one line naming the folder) an output folder that cannot be written
    or whose file system has less than ``SPACE_MARGIN`` times ``estimate`` bytes free (``what``: the
    output, a plural noun phrase of the message); a folder
    still to be made is judged by the nearest one that exists. Writing is tried with a file that
    has no name (nothing is left behind); the one place the free space is read."""
    folder = Path(folder)
    existing = folder.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        return  # not a folder: the output's own checks name it
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as error:
        raise DatasetError(f"{folder}: cannot write there ({error.strerror or error})") from None
    needed = SPACE_MARGIN * estimate
    free = shutil.disk_usage(existing).free
    if free < needed:
        raise DatasetError(
            f"{folder}: {what} need about {needed / 1e6:.1f} MB ({estimate / 1e6:.1f} MB estimated, times "
            f"{SPACE_MARGIN}) and {free / 1e6:.1f} MB are free: free some space or write elsewhere"
        )


class DatasetWriter:
    """Adds trials to a dataset directory, rewriting the manifest atomically after each one.

    Opening an existing dataset with a different header, or one of whose trial files (those its
    manifest names and that exist) is not a regular file, or adding a trial whose id or file exists
    with different data or cannot be read as text (module docstring), raises
    :class:`DatasetError` (nothing is overwritten silently); adding an identical trial again is a
    no-op. The kinds of the trial files are checked when the writer opens the dataset, before any
    trial is made.

    Space: a writer told how many trials are coming (``expected_trials``) measures the first
    one it writes and refuses to go on when the disk cannot hold the others
    (``SPACE_MARGIN`` times their size at the first one's); the trials written stay a dataset.
    """

    def __init__(self, directory: str | Path, header: DatasetHeader, expected_trials: int = 1):
        self.directory = Path(directory)
        self.header = header
        self.expected_trials = expected_trials
        self.written = 0
        self.entries: list[TrialEntry] = []
        manifest_path = self.directory / MANIFEST
        if manifest_path.exists():
            manifest = load_manifest(manifest_path)
            existing = {k: v for k, v in manifest.items() if k != "trials"}
            if json.loads(json.dumps(existing)) != json.loads(json.dumps(header.to_dict())):
                raise DatasetError(
                    f"{manifest_path} already holds a dataset with another header "
                    f"({existing}); refusing to overwrite it"
                )
            self.entries = [parse_entry(e) for e in manifest["trials"]]
            for entry in self.entries:  # a stat each, none read: a dataset of many trials opens at once
                for name in filter(None, (entry.file, entry.force_file)):
                    if (self.directory / name).exists():
                        regular_file(self.directory / name, "the trial file", DatasetError)

    def add_trial(self, entry: TrialEntry, log: TrialLog) -> None:
        files = {entry.file: _trial_csv(log, self.header.robot)}
        if entry.force_file is not None:
            if not log.has_force:
                raise DatasetError(f"trial {entry.id!r} names a force file but its log has no force")
            files[entry.force_file] = _force_csv(log)
        known = {e.id: e for e in self.entries}
        if entry.id in known:
            same = known[entry.id] == entry and all(
                _existing_text(self.directory / name) == text for name, text in files.items()
            )
            if same:
                return
            raise DatasetError(f"trial {entry.id!r} already exists in {self.directory} with other data")
        used = {e.file for e in self.entries} | {e.force_file for e in self.entries if e.force_file}
        for name, text in files.items():
            path = self.directory / name
            if name in used or _existing_text(path) not in (None, text):
                raise DatasetError(f"{path} already exists with other data; refusing to overwrite it")
        for name, text in files.items():
            write_text_atomic(self.directory / name, text)
        self.entries.append(entry)
        manifest = {**self.header.to_dict(), "trials": [e.to_dict() for e in self.entries]}
        write_text_atomic(self.directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")
        self.written += 1
        if self.written == 1:
            self._check_space(sum(len(text.encode()) for text in files.values()))

    def _check_space(self, first_bytes: int) -> None:
        """Refuse (DatasetError) when the free space cannot hold the trials still to come."""
        left = self.expected_trials - self.written
        if left > 0:
            check_room(self.directory, first_bytes * left,
                       f"the first trial took {first_bytes / 1e3:.0f} kB; the {left} left")


def _existing_text(path: Path) -> str | None:
    """The text of the trial file ``path``, None when there is none (a dangling link included);
    DatasetError naming it when it is not a regular UTF-8 text file (``files.read_text``)."""
    if not path.exists():
        return None
    return read_text(path, "the trial file", DatasetError)


def _csv(columns: list[str], table: np.ndarray) -> str:
    stream = io.StringIO()
    np.savetxt(stream, table, delimiter=",", header=",".join(columns), comments="", fmt="%.10g")
    return stream.getvalue()


def _trial_csv(log: TrialLog, robot: str) -> str:
    base = [log.base] if base_columns(robot) else []
    if base and len(log.base) != len(log.t):
        raise DatasetError(f"a {robot_description(robot).name} trial's log lacks the base state of its samples")
    return _csv(trial_columns(robot), np.column_stack([log.t, *base, log.q, log.dq, log.tau, log.dq_cmd]))


def _force_csv(log: TrialLog) -> str:
    return _csv(FORCE_COLUMNS, np.column_stack([log.force_t, log.force]))
