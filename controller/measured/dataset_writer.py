"""Writing an impact dataset (the format: ``dataset``): trials are added one by one, each file
atomically, the manifest rewritten after each; nothing different is ever overwritten."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import numpy as np

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
"""The free space a dataset writer asks for, in units of the trials still to come at the size of
the first one (a slower trial logs more samples)."""


class DatasetWriter:
    """Adds trials to a dataset directory, rewriting the manifest atomically after each one.

    Opening an existing dataset with a different header, or adding a trial whose id exists with
    different data, raises :class:`DatasetError` (nothing is overwritten silently); adding an
    identical trial again is a no-op.

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

    def add_trial(self, entry: TrialEntry, log: TrialLog) -> None:
        files = {entry.file: _trial_csv(log, self.header.robot)}
        if entry.force_file is not None:
            if not log.has_force:
                raise DatasetError(f"trial {entry.id!r} names a force file but its log has no force")
            files[entry.force_file] = _force_csv(log)
        known = {e.id: e for e in self.entries}
        if entry.id in known:
            same = known[entry.id] == entry and all(
                (self.directory / name).exists() and (self.directory / name).read_text() == text
                for name, text in files.items()
            )
            if same:
                return
            raise DatasetError(f"trial {entry.id!r} already exists in {self.directory} with other data")
        used = {e.file for e in self.entries} | {e.force_file for e in self.entries if e.force_file}
        for name, text in files.items():
            path = self.directory / name
            if name in used or (path.exists() and path.read_text() != text):
                raise DatasetError(f"{path} already exists with other data; refusing to overwrite it")
        for name, text in files.items():
            write_text_atomic(self.directory / name, text)
        self.entries.append(entry)
        manifest = {**self.header.to_dict(), "trials": [e.to_dict() for e in self.entries]}
        write_text_atomic(self.directory / MANIFEST, json.dumps(manifest, indent=2) + "\n")
        self.written += 1
        if self.written == 1:
            self._check_space(sum(len(text.encode()) for text in files.values()))

    def _check_space(self, trial_bytes: int) -> None:
        """Refuse (DatasetError) when the free space cannot hold the trials still to come."""
        left = self.expected_trials - self.written
        needed = SPACE_MARGIN * trial_bytes * left
        free = shutil.disk_usage(self.directory).free
        if left > 0 and free < needed:
            raise DatasetError(
                f"{self.directory}: the first trial took {trial_bytes / 1e3:.0f} kB; the {left} left need about "
                f"{needed / 1e6:.1f} MB and {free / 1e6:.1f} MB are free: free some space or write elsewhere"
            )


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
