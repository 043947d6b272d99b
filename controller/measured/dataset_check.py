"""The checks of a dataset (``impactqp dataset validate``): every problem of the manifest and of
each trial, found without modifying any file (format: ``docs/dataset.md``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from impactqp.controller.model.robot_description import RobotDescription, robot_description

from .dataset import (
    MANIFEST,
    DatasetError,
    DatasetHeader,
    TrialEntry,
    load_manifest,
    parse_entry,
    parse_header,
    read_trial,
)
from .dataset_robot import quaternion_problem
from .impact import WINDOW_AFTER, WINDOW_BEFORE, ImpactNotFoundError, measure_impact

POSITION_TOLERANCE = 1e-3
"""rad a logged joint position may lie outside the URDF limits (encoder and rounding)."""

GAP_STEPS = 1.5
"""A time step longer than this many control periods is a gap: samples are missing."""

JITTER_SHARE = 0.1
"""A time step (not a gap) further than this share of the control period from it is jitter."""

RATE_SHARE = 0.01
"""The mean regular time step may differ from the manifest's control period by this share."""


def samples_needed(control_period: float) -> int:
    """The fewest control samples of a trial whose impact the detection window can measure."""
    return int(round((WINDOW_BEFORE + WINDOW_AFTER) / control_period)) + 4


def validate(directory: str | Path, progress=None) -> dict[str, list[str]]:
    """Problems of a dataset, per trial id (key ``"dataset"`` for the manifest itself).

    Checks: the manifest (format, keys, header, duplicate ids, CSV files it does not list),
    per trial the files and their columns, non-finite values, increasing time, the joint positions
    against the robot's limits, a floating base's unit quaternions, the time stamps against
    ``control_period`` (:func:`timing_problems`: gaps, rate, jitter), a length that holds the detection window, an impact
    found by :func:`controller.measured.impact.measure_impact`, and ``impact_time`` against the detected impact.
    An empty list means no problem. Never modifies any file.

    Each file is read and checked once, however many trial entries name it, so the work grows
    linearly with the entries. ``progress(done, total)`` is an optional callable invoked once per
    trial entry.
    """
    directory = Path(directory)
    problems: dict[str, list[str]] = {"dataset": []}
    try:
        manifest = load_manifest(directory / MANIFEST)
        header = parse_header(manifest)
    except DatasetError as error:
        problems["dataset"].append(str(error))
        return problems
    listed = set()
    checked: dict[tuple[str, str | None], tuple[list[str], float | None]] = {}
    total = len(manifest["trials"])
    for index, raw in enumerate(manifest["trials"]):
        if progress:
            progress(index, total)
        try:
            entry = parse_entry(raw, header.surface.normal)
        except (DatasetError, TypeError, ValueError) as error:
            problems["dataset"].append(f"trial entry {index}: {error}")
            continue
        if entry.id in problems:
            problems["dataset"].append(f"trial id {entry.id!r} appears more than once")
            continue
        listed |= {entry.file, entry.force_file}
        files = (entry.file, entry.force_file)
        if files not in checked:
            checked[files] = _log_problems(directory, entry, header)
        problems[entry.id] = _trial_problems(entry, *checked[files])
    if progress:
        progress(total, total)
    unlisted = sorted(p.name for p in directory.glob("*.csv") if p.name not in listed)
    if unlisted:
        problems["dataset"].append(f"CSV file(s) not listed in the manifest: {', '.join(unlisted)}")
    return problems


def timing_problems(t: np.ndarray, control_period: float, name: str) -> list[str]:
    """The problems of a trial's time stamps ``t`` (increasing, s) against the manifest's
    ``control_period``, each named with where it is:

    - **gaps**: a step longer than :data:`GAP_STEPS` periods, round(step / period) - 1 samples
      missing (a dropped sample is one);
    - **a wrong sampling rate**: the mean of the other steps differs from the period by more than
      :data:`RATE_SHARE` of it (a mean, not a median: a log whose steps alternate is read right);
    - **jitter**: regular steps further than :data:`JITTER_SHARE` of the period from their mean
      (the time stamps wander, the rate is right), with the data rows after the first and the
      largest.
    """
    steps = np.diff(t)
    gap = steps > GAP_STEPS * control_period
    problems = []
    if np.any(gap):
        where = np.flatnonzero(gap)
        missing = int(np.sum(np.round(steps[where] / control_period) - 1))
        first = int(where[0])
        problems.append(
            f"{name}: {missing} sample(s) missing in {len(where)} gap(s), the first after t = {t[first]:.4f} s "
            f"(data row {first + 1}: the next sample comes {steps[first]:.6g} s later, the period is "
            f"{control_period:.6g} s)"
        )
    regular = steps[~gap]
    if len(regular) == 0:
        return problems
    period = float(np.mean(regular))
    if abs(period - control_period) > RATE_SHARE * control_period:
        problems.append(f"{name} is sampled every {period:.6g} s, the manifest says {control_period:.6g} s")
        return problems
    off = ~gap & (np.abs(steps - period) > JITTER_SHARE * control_period)
    if np.any(off):
        where = np.flatnonzero(off)
        worst = int(where[np.argmax(np.abs(steps[where] - period))])
        problems.append(
            f"{name}: the time stamps jitter: {len(where)} of {len(regular)} steps differ from the "
            f"{control_period:.6g} s period by more than {100 * JITTER_SHARE:.0f} %, the first after data row "
            f"{where[0] + 1} (t = {t[where[0]]:.4f} s), the largest ({abs(steps[worst] - period):.3g} s) after "
            f"data row {worst + 1}"
        )
    return problems


def _trial_problems(entry: TrialEntry, log_problems: list[str], impact_start: float | None) -> list[str]:
    """The problems of one trial entry: those of its files, and its ``impact_time`` against the
    impact found in them."""
    problems = list(log_problems)
    if impact_start is not None and entry.impact_time is not None:
        if abs(entry.impact_time - impact_start) > WINDOW_BEFORE:
            problems.append(
                f"impact_time {entry.impact_time:.4f} s disagrees with the impact found at {impact_start:.4f} s"
            )
    return problems


def joint_limit_problem(q: np.ndarray, robot: RobotDescription, file: str) -> str | None:
    """The first logged joint position (rows of ``q``) outside the robot's limits, beyond
    POSITION_TOLERANCE, as one line naming ``file``; None when every one lies inside."""
    outside = (q < robot.q_min - POSITION_TOLERANCE) | (q > robot.q_max + POSITION_TOLERANCE)
    if not np.any(outside):
        return None
    row, joint = (int(i) for i in np.argwhere(outside)[0])
    return (
        f"{file}: q{joint + 1} = {q[row, joint]:.4f} rad at data row {row + 1} lies outside "
        f"the joint limits [{robot.q_min[joint]:.4f}, {robot.q_max[joint]:.4f}]"
    )


def _log_problems(directory: Path, entry: TrialEntry, header: DatasetHeader) -> tuple[list[str], float | None]:
    """The problems of the files of ``entry`` (its CSV and force CSV), checked against the
    header's robot and control period, and the start of the impact found in them (None when none
    is found)."""
    try:
        log = read_trial(directory, entry, header.robot)
    except DatasetError as error:
        return [str(error)], None
    problems = []
    control_period = header.control_period
    robot = robot_description(header.robot)
    outside = joint_limit_problem(log.q, robot, entry.file)
    if outside is not None:
        return [outside], None
    quaternion = quaternion_problem(log.base, entry.file) if robot.floating else None
    if quaternion is not None:
        return [quaternion], None
    needed = samples_needed(control_period)
    if len(log) < 2:
        return [f"{entry.file} holds {len(log)} samples, fewer than the {needed} of the detection window"], None
    problems += timing_problems(log.t, control_period, entry.file)
    if len(log) < needed:
        problems.append(
            f"{entry.file} holds {len(log)} samples, fewer than the {needed} of the detection window"
        )
        return problems, None
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError as error:
        problems.append(f"no impact found: {error}")
        return problems, None
    return problems, impact.t_contact_start
