"""Impact datasets: what a real robot log holds, for simulated and measured trials alike.

A dataset is a directory with a manifest ``dataset.json``::

    {
      "format": "impactqp-dataset/1",
      "robot": "panda",
      "tool": {"frame": "panda_hand", "contact_point": [0, 0, 0.14]},
      "surface": {"point": [0.6, 0, 0], "normal": [-1, 0, 0], "friction": 0.1123},
      "control_period": 0.001,
      "trials": [{"id": "t000", "file": "t000.csv", "force_file": "t000_force.csv",
                  "reference_normal_speed": 0.15, "reference_tangential_velocity": [0, 0, 0],
                  "posture": "elbow_up", "impact_time": 0.134}]
    }

``tool.contact_point`` is the contact point in ``tool.frame`` (a frame of the robot
description); the surface is in the world frame with its normal towards the robot. Per trial,
one CSV at the control rate with the columns ``t, q1..q7, dq1..dq7, tau1..tau7, dq_cmd1..dq_cmd7``
(tau: measured joint torques, dq_cmd: commanded joint velocities) and optionally a force CSV
``t, fx, fy, fz`` (force on the robot at the contact, world frame, any rate). ``force_file``,
``reference_tangential_velocity``, ``posture`` and ``impact_time`` are optional.

A dataset never records plant parameters: they are simulation truth, not measurements.
Every file is written atomically (temporary file + os.replace), and a writer never replaces an
existing, different manifest or trial file silently. :func:`validate` only reads.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import NQ
from impactqp.controller.model.validation import BadInputError

from .atomic import write_text_atomic
from .impact import WINDOW_AFTER, WINDOW_BEFORE, ImpactNotFoundError, measure_impact
from .json_file import read_json_object
from .trial_log import TrialLog

FORMAT = "impactqp-dataset/1"
MANIFEST = "dataset.json"
TRIAL_COLUMNS = (
    ["t"]
    + [f"q{i}" for i in range(1, NQ + 1)]
    + [f"dq{i}" for i in range(1, NQ + 1)]
    + [f"tau{i}" for i in range(1, NQ + 1)]
    + [f"dq_cmd{i}" for i in range(1, NQ + 1)]
)
FORCE_COLUMNS = ["t", "fx", "fy", "fz"]
MANIFEST_KEYS = {"format", "robot", "tool", "surface", "control_period", "trials"}
TRIAL_KEYS = {"id", "file", "reference_normal_speed"}
OPTIONAL_TRIAL_KEYS = {"force_file", "reference_tangential_velocity", "posture", "impact_time"}


class DatasetError(BadInputError):
    """A dataset that cannot be read or written as asked."""


@dataclass(frozen=True)
class Tool:
    """The contact point ``contact_point`` (m) expressed in the robot frame ``frame``."""

    frame: str
    contact_point: tuple[float, float, float]


@dataclass(frozen=True)
class TrialEntry:
    """One trial of the manifest."""

    id: str
    file: str
    reference_normal_speed: float
    force_file: str | None = None
    reference_tangential_velocity: tuple[float, float, float] | None = None
    posture: str | None = None
    impact_time: float | None = None

    def to_dict(self) -> dict:
        entry = {"id": self.id, "file": self.file, "reference_normal_speed": self.reference_normal_speed}
        if self.force_file is not None:
            entry["force_file"] = self.force_file
        if self.reference_tangential_velocity is not None:
            entry["reference_tangential_velocity"] = list(self.reference_tangential_velocity)
        if self.posture is not None:
            entry["posture"] = self.posture
        if self.impact_time is not None:
            entry["impact_time"] = self.impact_time
        return entry


@dataclass(frozen=True)
class DatasetHeader:
    """Everything of the manifest but the trial list."""

    tool: Tool
    surface: Surface
    control_period: float
    robot: str = "panda"

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "robot": self.robot,
            "tool": {"frame": self.tool.frame, "contact_point": list(self.tool.contact_point)},
            "surface": {
                "point": self.surface.point.tolist(),
                "normal": self.surface.normal.tolist(),
                "friction": self.surface.friction,
            },
            "control_period": self.control_period,
        }


@dataclass(frozen=True)
class DatasetTrial:
    entry: TrialEntry
    log: TrialLog


@dataclass(frozen=True)
class Dataset:
    directory: Path
    header: DatasetHeader
    trials: list[DatasetTrial]


# ---------------------------------------------------------------------------- writing
class DatasetWriter:
    """Adds trials to a dataset directory, rewriting the manifest atomically after each one.

    Opening an existing dataset with a different header, or adding a trial whose id exists with
    different data, raises :class:`DatasetError` (nothing is overwritten silently); adding an
    identical trial again is a no-op.
    """

    def __init__(self, directory: str | Path, header: DatasetHeader):
        self.directory = Path(directory)
        self.header = header
        self.entries: list[TrialEntry] = []
        manifest_path = self.directory / MANIFEST
        if manifest_path.exists():
            manifest = _load_manifest(manifest_path)
            existing = {k: v for k, v in manifest.items() if k != "trials"}
            if json.loads(json.dumps(existing)) != json.loads(json.dumps(header.to_dict())):
                raise DatasetError(
                    f"{manifest_path} already holds a dataset with another header "
                    f"({existing}); refusing to overwrite it"
                )
            self.entries = [_parse_entry(e) for e in manifest["trials"]]

    def add_trial(self, entry: TrialEntry, log: TrialLog) -> None:
        files = {entry.file: _trial_csv(log)}
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


def _csv(columns: list[str], table: np.ndarray) -> str:
    stream = io.StringIO()
    np.savetxt(stream, table, delimiter=",", header=",".join(columns), comments="", fmt="%.10g")
    return stream.getvalue()


def _trial_csv(log: TrialLog) -> str:
    return _csv(TRIAL_COLUMNS, np.column_stack([log.t, log.q, log.dq, log.tau, log.dq_cmd]))


def _force_csv(log: TrialLog) -> str:
    return _csv(FORCE_COLUMNS, np.column_stack([log.force_t, log.force]))


# ---------------------------------------------------------------------------- reading
def _load_manifest(path: Path) -> dict:
    manifest = read_json_object(path, DatasetError, "{path} does not exist: not a dataset directory")
    missing = MANIFEST_KEYS - set(manifest)
    if missing:
        raise DatasetError(f"{path} lacks the key(s) {', '.join(sorted(missing))}")
    if manifest["format"] != FORMAT:
        raise DatasetError(f"{path}: format {manifest['format']!r} is not {FORMAT!r}")
    if not isinstance(manifest["trials"], list):
        raise DatasetError(f"{path}: 'trials' must be a list")
    return manifest


def _parse_header(manifest: dict) -> DatasetHeader:
    try:
        tool = manifest["tool"]
        point = np.asarray(tool["contact_point"], dtype=float)
        if point.shape != (3,):
            raise DatasetError("tool.contact_point needs 3 values")
        surface = manifest["surface"]
        period = float(manifest["control_period"])
        if not (np.isfinite(period) and period > 0.0):
            raise DatasetError(f"control_period = {period} s must be > 0")
        return DatasetHeader(
            tool=Tool(str(tool["frame"]), tuple(float(x) for x in point)),
            surface=Surface(
                surface["point"], surface["normal"], *([float(surface["friction"])] if "friction" in surface else [])
            ),
            control_period=period,
            robot=str(manifest["robot"]),
        )
    except (KeyError, TypeError, ValueError) as error:
        if isinstance(error, DatasetError):
            raise
        raise DatasetError(f"bad tool, surface or control_period in the manifest: {error!r}") from None


def _parse_entry(entry: dict) -> TrialEntry:
    if not isinstance(entry, dict):
        raise DatasetError(f"a trial entry must be an object, got {entry!r}")
    missing = TRIAL_KEYS - set(entry)
    if missing:
        raise DatasetError(f"trial entry {entry.get('id', '?')!r} lacks {', '.join(sorted(missing))}")
    unknown = set(entry) - TRIAL_KEYS - OPTIONAL_TRIAL_KEYS
    if unknown:
        raise DatasetError(f"trial entry {entry['id']!r} has unknown key(s) {', '.join(sorted(unknown))}")
    tangential = entry.get("reference_tangential_velocity")
    if tangential is not None:
        tangential = tuple(float(x) for x in tangential)
        if len(tangential) != 3:
            raise DatasetError(f"trial {entry['id']!r}: reference_tangential_velocity needs 3 values")
    impact_time = entry.get("impact_time")
    return TrialEntry(
        id=str(entry["id"]),
        file=str(entry["file"]),
        reference_normal_speed=float(entry["reference_normal_speed"]),
        force_file=entry.get("force_file"),
        reference_tangential_velocity=tangential,
        posture=entry.get("posture"),
        impact_time=None if impact_time is None else float(impact_time),
    )


def _read_table(path: Path, columns: list[str]) -> np.ndarray:
    """The table of a CSV file with exactly-named columns, in ``columns`` order."""
    try:
        with path.open() as stream:
            header = stream.readline().strip().split(",")
            table = np.loadtxt(stream, delimiter=",", ndmin=2)
    except FileNotFoundError:
        raise DatasetError(f"{path.name} does not exist") from None
    except ValueError as error:
        raise DatasetError(f"{path.name} is not a numeric CSV: {error}") from None
    header = [name.strip() for name in header]
    missing = [c for c in columns if c not in header]
    if missing:
        raise DatasetError(f"{path.name} lacks the column(s) {', '.join(missing)}")
    if table.shape[0] == 0:
        raise DatasetError(f"{path.name} holds no samples")
    if table.shape[1] != len(header):
        raise DatasetError(f"{path.name}: {table.shape[1]} values per row for {len(header)} columns")
    table = table[:, [header.index(c) for c in columns]]
    if not np.all(np.isfinite(table)):
        row = int(np.flatnonzero(~np.all(np.isfinite(table), axis=1))[0])
        raise DatasetError(f"{path.name} holds a NaN or infinite value (data row {row + 1})")
    if np.any(np.diff(table[:, 0]) <= 0.0):
        row = int(np.flatnonzero(np.diff(table[:, 0]) <= 0.0)[0])
        raise DatasetError(f"{path.name}: time does not increase at data row {row + 2}")
    return table


def read_trial(directory: Path, entry: TrialEntry) -> TrialLog:
    table = _read_table(directory / entry.file, TRIAL_COLUMNS)
    t, q, dq, tau, dq_cmd = (table[:, 0], *np.split(table[:, 1:], 4, axis=1))
    log = TrialLog(t, q, dq, tau, dq_cmd)
    if entry.force_file is not None:
        force = _read_table(directory / entry.force_file, FORCE_COLUMNS)
        log.force_t, log.force = force[:, 0], force[:, 1:]
    return log


def read_dataset(directory: str | Path, skip: frozenset[str] | set[str] = frozenset()) -> Dataset:
    """Read a dataset, leaving out the trials whose ids are in ``skip``; raises
    :class:`DatasetError` on the first problem (see :func:`validate`)."""
    directory = Path(directory)
    manifest = _load_manifest(directory / MANIFEST)
    header = _parse_header(manifest)
    trials = []
    for raw in manifest["trials"]:
        entry = _parse_entry(raw)
        if entry.id in skip:
            continue
        try:
            trials.append(DatasetTrial(entry, read_trial(directory, entry)))
        except DatasetError as error:
            raise DatasetError(f"trial {entry.id!r}: {error}") from None
    return Dataset(directory, header, trials)


# ---------------------------------------------------------------------------- validation
def validate(directory: str | Path) -> dict[str, list[str]]:
    """Problems of a dataset, per trial id (key ``"dataset"`` for the manifest itself).

    Checks: the manifest (format, keys, header, duplicate ids, CSV files it does not list),
    per trial the files and their columns, non-finite values, increasing time, the sampling
    period against ``control_period``, a length that holds the detection window, an impact
    found by :func:`controller.measured.impact.measure_impact`, and ``impact_time`` against the detected impact.
    An empty list means no problem. Never modifies any file.
    """
    directory = Path(directory)
    problems: dict[str, list[str]] = {"dataset": []}
    try:
        manifest = _load_manifest(directory / MANIFEST)
        header = _parse_header(manifest)
    except DatasetError as error:
        problems["dataset"].append(str(error))
        return problems
    listed = set()
    for index, raw in enumerate(manifest["trials"]):
        try:
            entry = _parse_entry(raw)
        except (DatasetError, TypeError, ValueError) as error:
            problems["dataset"].append(f"trial entry {index}: {error}")
            continue
        if entry.id in problems:
            problems["dataset"].append(f"trial id {entry.id!r} appears more than once")
            continue
        listed |= {entry.file, entry.force_file}
        problems[entry.id] = _trial_problems(directory, entry, header.control_period)
    unlisted = sorted(p.name for p in directory.glob("*.csv") if p.name not in listed)
    if unlisted:
        problems["dataset"].append(f"CSV file(s) not listed in the manifest: {', '.join(unlisted)}")
    return problems


def _trial_problems(directory: Path, entry: TrialEntry, control_period: float) -> list[str]:
    try:
        log = read_trial(directory, entry)
    except DatasetError as error:
        return [str(error)]
    problems = []
    needed = int(round((WINDOW_BEFORE + WINDOW_AFTER) / control_period)) + 4
    if len(log) < 2:
        return [f"{entry.file} holds {len(log)} samples, fewer than the {needed} of the detection window"]
    period = log.control_period
    if abs(period - control_period) > 0.01 * control_period:
        problems.append(
            f"{entry.file} is sampled every {period:.6g} s, the manifest says {control_period:.6g} s"
        )
    if len(log) < needed:
        problems.append(
            f"{entry.file} holds {len(log)} samples, fewer than the {needed} of the detection window"
        )
        return problems
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError as error:
        problems.append(f"no impact found: {error}")
        return problems
    if entry.impact_time is not None and abs(entry.impact_time - impact.t_contact_start) > WINDOW_BEFORE:
        problems.append(
            f"impact_time {entry.impact_time:.4f} s disagrees with the impact found at "
            f"{impact.t_contact_start:.4f} s"
        )
    return problems
