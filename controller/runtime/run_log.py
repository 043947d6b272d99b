"""The dataset a run is added to (``impactqp run --log DIR``), opened before the run.

Opening checks everything that could refuse the log (the directory can be created and written,
an existing dataset there has the same header), so that a robot never moves for a log that
cannot be kept; ``add`` then writes the run as one trial ``runNNNN`` (``docs/dataset.md``) and
``add_robot`` what a robot run set and did beside it (``runNNNN_robot.json``: the collision
thresholds, the start move; ``docs/robot-loop.md``), outside the dataset's manifest.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import DatasetError, DatasetHeader, TrialEntry
from impactqp.controller.measured.dataset_writer import DatasetWriter
from impactqp.controller.measured.dataset_check import samples_needed
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.validation import BadInputError


class RunLog:
    """One trial to add to the dataset in ``directory`` with ``header``."""

    def __init__(self, directory: str, header: DatasetHeader):
        self.directory = Path(directory)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            if not os.access(self.directory, os.W_OK | os.X_OK):
                raise BadInputError(f"--log {directory}: the directory is not writable")
            self.writer = DatasetWriter(self.directory, header)
        except (DatasetError, OSError) as error:
            raise BadInputError(f"--log {directory}: {error}") from None
        self.trial_id = f"run{len(self.writer.entries):04d}"

    def add(self, log: TrialLog, speed: float, posture: str | None, impact_time: float | None) -> str | None:
        """Write the trial, up to its last measured sample (a lost connection logs NaN
        placeholders from then on); the path of its CSV, or None when fewer samples than a
        trial needs were measured (``dataset_check.samples_needed``): a complete trial or none."""
        log = measured_part(log)
        if len(log) < samples_needed(self.writer.header.control_period):
            return None
        entry = TrialEntry(
            id=self.trial_id,
            file=f"{self.trial_id}.csv",
            reference_normal_speed=speed,
            force_file=f"{self.trial_id}_force.csv" if log.has_force else None,
            posture=posture,
            impact_time=impact_time,
        )
        try:
            self.writer.add_trial(entry, log)
        except (DatasetError, OSError) as error:
            raise BadInputError(f"--log {self.directory}: {error}") from None
        return str(self.directory / entry.file)


    def add_robot(self, robot: dict, start_move: dict | None) -> str:
        """Write a robot run's report entries ``robot`` and ``start_move`` beside its trial; the
        file's path."""
        path = self.directory / f"{self.trial_id}_robot.json"
        try:
            path.write_text(json.dumps({"robot": robot, "start_move": start_move}, indent=1) + "\n")
        except OSError as error:
            raise BadInputError(f"--log {self.directory}: {error}") from None
        return str(path)


def measured_part(log: TrialLog) -> TrialLog:
    """The log up to its first sample with a non-finite value (excluded): what was measured
    before a read failed."""
    finite = np.isfinite(log.q).all(axis=1) & np.isfinite(log.dq).all(axis=1) & np.isfinite(log.tau).all(axis=1)
    if finite.all():
        return log
    first = int(np.argmin(finite))
    return log.truncated(float(log.t[first]))

