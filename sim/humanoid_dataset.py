"""Simulated G1 trials as a dataset (``controller.measured.dataset``, docs/dataset.md: "simulated
and measured trials alike"): what ``simulate --robot g1 --out DIR`` and ``campaign --robot g1``
write.

The world frame of a G1 dataset is the simulation's moved along x onto the wall plane: the wall
is the surface through the origin with normal (-1, 0, 0) whatever the stance (each stance puts
its wall 2 cm, with the whole-body QP 5 cm, in front of its hand), so that the trials of every
stance and command source share one manifest. A real humanoid's state estimator has its own
origin too; only the base position's x column depends on the choice. The trial's ``ImpactTrial.log``
holds the rows (the servo's torque of row k held over [t_k, t_k+1), the wall force per physics
step); its first contact is the manifest's ``impact_time``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import DatasetHeader, DatasetWriter, TrialEntry
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import ROBOTS, RobotDescription

from .scene import WALL_FRICTION
from .humanoid_trial import CONTROL_PERIOD, NORMAL, ImpactTrial


def humanoid_header(robot: RobotDescription) -> DatasetHeader:
    """The manifest header of the simulated trials of the floating-base ``robot``: its contact
    frame, the wall through the origin (module docstring), the trial's control period."""
    return DatasetHeader.of(RobotChoice(robot), Surface(np.zeros(3), NORMAL, WALL_FRICTION), CONTROL_PERIOD)


def trial_id(trial: ImpactTrial) -> str:
    """A file-name-safe id naming the stance, the commanded speed (mm/s) and the command source."""
    return f"{trial.stance}_vn{round(trial.speed * 1000):d}_{trial.source}"


def dataset_log(trial: ImpactTrial) -> TrialLog:
    """The trial's log in the dataset's world frame (module docstring): the base's x minus the wall's."""
    base = trial.log.base.copy()
    base[:, 0] -= trial.wall_x
    return replace(trial.log, base=base)


def trial_entry(trial: ImpactTrial) -> TrialEntry:
    """The manifest's entry of a trial: its files, commanded speed, stance and first wall contact."""
    name = trial_id(trial)
    return TrialEntry(
        id=name, file=f"{name}.csv", reference_normal_speed=trial.speed, force_file=f"{name}_force.csv",
        reference_tangential_velocity=(0.0, 0.0, 0.0), posture=trial.stance,
        impact_time=trial.contact_index * CONTROL_PERIOD,
    )


def open_dataset(directory: str | Path, robot: RobotDescription = ROBOTS["g1"]) -> DatasetWriter:
    """The writer of the dataset of ``robot``'s trials in ``directory`` (created with the first
    trial); an existing dataset of another header is refused here, before any trial is simulated."""
    return DatasetWriter(directory, humanoid_header(robot))


def write_trials(writer: DatasetWriter, trials) -> list[TrialEntry]:
    """Add ``trials`` (``ImpactTrial``) to the dataset of ``writer`` (``open_dataset``); a trial of
    an id the dataset holds with other data is refused, the same trial again changes nothing."""
    entries = []
    for trial in trials:
        entries.append(trial_entry(trial))
        writer.add_trial(entries[-1], dataset_log(trial))
    return entries
