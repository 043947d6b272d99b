"""Impact datasets: what a real robot log holds, for simulated and measured trials alike.

A dataset is a directory with a manifest ``dataset.json``::

    {
      "format": "impactqp-dataset/1",
      "robot": "panda",
      "tool": {"name": "impact_tip", "frame": "hand", "replaces_hand": false,
               "geometry": {"shape": "sphere", "radius": 0.02, "centre": [0, 0, 0.12]},
               "contact_point": [0, 0, 0.14], "mass": 0.0, "com": [0, 0, 0], "inertia": [[0, 0, 0], ...]},
      "surface": {"point": [0.6, 0, 0], "normal": [-1, 0, 0], "friction": 0.1123},
      "control_period": 0.001,
      "trials": [{"id": "t000", "file": "t000.csv", "force_file": "t000_force.csv",
                  "reference_normal_speed": 0.15, "reference_tangential_velocity": [0, 0, 0],
                  "posture": "elbow_up", "impact_time": 0.134}]
    }

``robot`` names a robot description (``panda``, ``fr3``, ``ur5``, ``g1``, or a description file) and
``tool`` is the full tool description (``tool_description.ToolDescription.as_dict``; docs/dataset.md): whoever reads the
dataset models that robot and that tool. A floating-base robot (the G1) carries no tool: its
``tool`` is its own contact frame and its base state comes before its joints' columns
(``dataset_robot``). A manifest of the first version, whose tool is
``{"frame": "panda_hand", "contact_point": [0, 0, 0.14]}`` (the hand frame of its robot and the
impact tip's contact point), is read as the built-in ``impact_tip``. The surface is in the world frame with its normal towards the robot. Per trial,
one CSV at the control rate with the columns ``t, q1..qn, dq1..dqn, tau1..taun, dq_cmd1..dq_cmdn`` (n joints;
a floating base's 13 columns after ``t``)
(tau: measured joint torques, dq_cmd: commanded joint velocities) and optionally a force CSV
``t, fx, fy, fz`` (force on the robot at the contact, world frame, any rate). ``force_file``,
``reference_tangential_velocity``, ``posture`` and ``impact_time`` are optional, and so is the
manifest's ``encoder_step`` (rad/s per joint: the step to which the logged dq is quantised).

A dataset never records plant parameters: they are simulation truth, not measurements.
Every file is written atomically (temporary file + os.replace), and a writer never replaces an
existing, different manifest or trial file silently. :func:`validate` only reads.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import ROBOT_FILE_SUFFIXES, ROBOTS, robot_description
from impactqp.controller.model.tool_description import TOOLS, ToolDescription, tool_from_dict
from impactqp.controller.model.files import read_mapping, regular_file
from impactqp.controller.model.validation import (
    BadInputError,
    approach_speed,
    file_inside,
    non_empty_string,
    number,
    numbers,
)

from .dataset_robot import BASE_COLUMNS, ContactFrame, base_columns, contact_frame_from_dict, trial_columns
from .trial_log import TrialLog

FORMAT = "impactqp-dataset/1"
MANIFEST = "dataset.json"


TRIAL_COLUMNS = trial_columns("panda")
FORCE_COLUMNS = ["t", "fx", "fy", "fz"]
RESERVED_ID = "dataset"
"""The key of the manifest's own problems in :func:`validate`; no trial may use it."""
MIN_CONTROL_PERIOD, MAX_CONTROL_PERIOD = 1e-4, 1e-2
"""s: the control periods a log may have (10 kHz to 100 Hz)."""
DIRECTORY = "the dataset directory"
"""Where every file a manifest names must lie."""
T = TypeVar("T")
MANIFEST_KEYS = {"format", "robot", "tool", "surface", "control_period", "trials"}
MAX_ENCODER_STEP = 0.1
"""rad/s: the coarsest quantisation of dq a manifest may declare (``encoder_step``)."""
TRIAL_KEYS = {"id", "file", "reference_normal_speed"}
IN_PLANE_TOLERANCE = 1e-6
"""m/s per m/s: the largest component along the wall's normal a tangential velocity may have."""
OPTIONAL_TRIAL_KEYS = {"force_file", "reference_tangential_velocity", "posture", "impact_time"}


class DatasetError(BadInputError):
    """A dataset that cannot be read or written as asked."""


LEGACY_TOOL_KEYS = {"frame", "contact_point"}
"""The tool of a first-version manifest: a frame of the robot and a contact point in it."""

TOOL_TOLERANCE = 1e-6
"""m: a legacy contact point this close to the impact tip's is the impact tip (JSON round trips)."""


def _legacy_tool(tool: dict, robot: str) -> ToolDescription:
    """The built-in ``impact_tip`` of a first-version tool ``{"frame", "contact_point"}``;
    bad input for any other legacy tool, whose geometry and mass the manifest does not say."""
    tip = TOOLS["impact_tip"]
    frame = non_empty_string(tool["frame"], "tool.frame")
    point = numbers(tool["contact_point"], 3, "tool.contact_point")
    same_point = np.allclose(point, tip.contact_point, rtol=0.0, atol=TOOL_TOLERANCE)
    if frame != robot_description(robot).hand_frame or not same_point:
        raise DatasetError(
            f"the manifest's tool (frame {frame!r}, contact point {[round(float(x), 6) for x in point]} m) "
            f"is not the impact tool (frame {robot_description(robot).hand_frame!r}, contact point "
            f"{tip.contact_point.tolist()} m); give the full tool description instead (docs/dataset.md)"
        )
    return tip


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
    """Everything of the manifest but the trial list. ``friction_known`` is false when the data
    do not know the surface's friction coefficient (a real robot's log; the manifest leaves
    ``surface.friction`` out and ``surface`` holds the default). ``encoder_step``, when the
    manifest declares it, is the step (rad/s) to which each joint's logged dq is quantised
    (0: not quantised), one per joint."""

    tool: ToolDescription | ContactFrame
    surface: Surface
    control_period: float
    robot: str = "panda"
    friction_known: bool = True
    encoder_step: tuple[float, ...] | None = None

    @classmethod
    def of(cls, choice: RobotChoice, surface: Surface, control_period: float) -> DatasetHeader:
        """The header of trials of ``choice``'s robot with its tool (a floating-base robot: its
        own contact frame, ``dataset_robot.ContactFrame``)."""
        tool = ContactFrame.of(choice.robot) if choice.robot.floating else choice.tool
        return cls(tool=tool, surface=surface, control_period=control_period, robot=choice.robot_setting)

    @property
    def choice(self) -> RobotChoice:
        """The robot and the tool the data were taken with: what a reader models (an arm's only)."""
        if robot_description(self.robot).floating:
            raise DatasetError(f"a {robot_description(self.robot).name} dataset (a floating base) cannot be read here: this reads "
                               f"datasets of the arms ({', '.join(n for n in ROBOTS if not ROBOTS[n].floating)}) only")
        return RobotChoice.of(self.robot, self.tool)

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "robot": self.robot,
            "tool": self.tool.as_dict(),
            "surface": {
                "point": self.surface.point.tolist(),
                "normal": self.surface.normal.tolist(),
                **({"friction": self.surface.friction} if self.friction_known else {}),
            },
            "control_period": self.control_period,
            **({"encoder_step": list(self.encoder_step)} if self.encoder_step is not None else {}),
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


# ---------------------------------------------------------------------------- reading
def load_manifest(path: Path) -> dict:
    manifest = read_mapping(path, "the dataset manifest", "json", DatasetError)
    missing = MANIFEST_KEYS - set(manifest)
    if missing:
        raise DatasetError(f"{path} lacks the key(s) {', '.join(sorted(missing))}")
    if manifest["format"] != FORMAT:
        raise DatasetError(f"{path}: the format must be {FORMAT!r}")
    robot = manifest["robot"]
    if not isinstance(robot, str) or (robot not in ROBOTS and Path(robot).suffix.lower() not in ROBOT_FILE_SUFFIXES):
        raise DatasetError(
            f"{path}: 'robot' must be one of the robots we model ({', '.join(ROBOTS)}) or a robot description file"
        )
    if not isinstance(manifest["trials"], list):
        raise DatasetError(f"{path}: 'trials' must be a list")
    return manifest


def _dataset_errors(parse: Callable[..., T]) -> Callable[..., T]:
    """``parse`` with the bad input of the shared validators raised as :class:`DatasetError`
    (``validate`` reports a dataset's problems, it does not stop at them)."""

    @functools.wraps(parse)
    def parse_dataset(value: dict, *context) -> T:
        try:
            return parse(value, *context)
        except DatasetError:
            raise
        except BadInputError as error:
            raise DatasetError(str(error)) from None

    return parse_dataset


@_dataset_errors
def parse_header(manifest: dict) -> DatasetHeader:
    tool, surface = manifest["tool"], manifest["surface"]
    if not isinstance(tool, dict):
        raise DatasetError("'tool' must be an object: a tool description (docs/dataset.md)")
    if not isinstance(surface, dict) or not {"point", "normal"} <= set(surface) <= {"point", "normal", "friction"}:
        raise DatasetError("'surface' must be an object with the keys point, normal and optionally friction")
    if robot_description(manifest["robot"]).floating:
        tool = contact_frame_from_dict(tool, manifest["robot"])
    elif set(tool) == LEGACY_TOOL_KEYS:
        tool = _legacy_tool(tool, manifest["robot"])
    else:
        try:
            tool = tool_from_dict(tool)
        except BadInputError as error:
            raise DatasetError(f"tool: {error}") from None
    period = number(manifest["control_period"], "control_period")
    if not (np.isfinite(period) and MIN_CONTROL_PERIOD <= period <= MAX_CONTROL_PERIOD):
        raise DatasetError(
            f"control_period must lie in [{MIN_CONTROL_PERIOD}, {MAX_CONTROL_PERIOD}] s, got {period}"
        )
    friction = [number(surface["friction"], "surface.friction")] if "friction" in surface else []
    point, normal = numbers(surface["point"], 3, "surface.point"), numbers(surface["normal"], 3, "surface.normal")
    try:
        plane = Surface(point, normal, *friction)
    except BadInputError as error:
        raise DatasetError(f"surface: {error}") from None
    return DatasetHeader(
        tool=tool, surface=plane, control_period=period, robot=manifest["robot"],
        friction_known=bool(friction), encoder_step=_encoder_step(manifest),
    )


def _encoder_step(manifest: dict) -> tuple[float, ...] | None:
    """The manifest's optional ``encoder_step``: one step per joint of its robot, each in
    [0, ``MAX_ENCODER_STEP``] rad/s (0: that joint's dq is not quantised); None when absent."""
    if "encoder_step" not in manifest:
        return None
    joints = len(robot_description(manifest["robot"]).joints)
    steps = np.array(numbers(manifest["encoder_step"], joints, "encoder_step"))
    if not np.all((steps >= 0.0) & (steps <= MAX_ENCODER_STEP)):
        raise DatasetError(
            f"encoder_step must be {joints} steps of dq in [0, {MAX_ENCODER_STEP:g}] rad/s (0: not quantised), "
            f"got {[float(x) for x in steps]}"
        )
    return tuple(float(x) for x in steps)


@_dataset_errors
def parse_entry(entry: dict, normal: np.ndarray | None = None) -> TrialEntry:
    """One trial of the manifest, every value type-checked; messages name the trial and the key.
    With the wall's ``normal``, a ``reference_tangential_velocity`` must lie in the wall's plane
    (its component along the normal at most ``IN_PLANE_TOLERANCE``)."""
    if not isinstance(entry, dict):
        raise DatasetError(f"a trial entry must be an object, got a {type(entry).__name__}")
    trial_id = entry.get("id")
    label = f"trial {trial_id!r}" if isinstance(trial_id, str) else "a trial entry"
    missing = TRIAL_KEYS - set(entry)
    if missing:
        raise DatasetError(f"{label} lacks {', '.join(sorted(missing))}")
    unknown = set(entry) - TRIAL_KEYS - OPTIONAL_TRIAL_KEYS
    if unknown:
        raise DatasetError(f"{label} has unknown key(s) {', '.join(sorted(map(str, unknown)))}")
    trial_id = non_empty_string(trial_id, "a trial's id")
    if trial_id == RESERVED_ID:
        raise DatasetError(f"the trial id {RESERVED_ID!r} is reserved for the manifest's own problems")
    what = f"{label}: reference_normal_speed"
    speed = approach_speed(number(entry["reference_normal_speed"], what), what)
    tangential = entry.get("reference_tangential_velocity")
    if tangential is not None:
        tangential = numbers(tangential, 3, f"{label}: reference_tangential_velocity")
        if not all(np.isfinite(tangential)):
            raise DatasetError(f"{label}: reference_tangential_velocity must be finite")
        along = 0.0 if normal is None else float(np.dot(tangential, normal))
        if abs(along) > IN_PLANE_TOLERANCE * max(1.0, float(np.linalg.norm(tangential))):
            raise DatasetError(
                f"{label}: reference_tangential_velocity must lie in the wall's plane, its component along the "
                f"normal is {along:.4g} m/s (the normal speed is reference_normal_speed)"
            )
    impact_time = entry.get("impact_time")
    if impact_time is not None:
        impact_time = number(impact_time, f"{label}: impact_time")
        if not 0.0 <= impact_time < float("inf"):
            raise DatasetError(f"{label}: impact_time must be a finite time >= 0 s, got {impact_time}")
    posture = entry.get("posture")
    force_file = entry.get("force_file")
    return TrialEntry(
        id=trial_id,
        file=file_inside(entry["file"], f"{label}: file", DIRECTORY),
        reference_normal_speed=speed,
        force_file=None if force_file is None else file_inside(force_file, f"{label}: force_file", DIRECTORY),
        reference_tangential_velocity=tangential,
        posture=None if posture is None else non_empty_string(posture, f"{label}: posture"),
        impact_time=impact_time,
    )


def _read_table(path: Path, columns: list[str]) -> np.ndarray:
    """The table of a CSV file with exactly-named columns, in ``columns`` order."""
    regular_file(path, "", DatasetError, shown=path.name)  # never open a FIFO or a device: it could block
    try:
        with path.open(encoding="utf-8-sig") as stream:  # a byte-order mark is not part of a name
            header = stream.readline().strip().split(",")
            with warnings.catch_warnings():  # no rows: reported below as "holds no samples"
                warnings.simplefilter("ignore", UserWarning)
                table = np.loadtxt(stream, delimiter=",", ndmin=2)
    except FileNotFoundError:
        raise DatasetError(f"{path.name} does not exist") from None
    except IsADirectoryError:
        raise DatasetError(f"{path.name} is a directory, not a CSV file") from None
    except (ValueError, UnicodeDecodeError):
        # never echo the file's content: it may be anything the manifest pointed at
        raise DatasetError(f"{path.name} is not a numeric CSV file") from None
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


def _inside(directory: Path, name: str) -> Path:
    """``directory / name``, refused when a link leads it outside the dataset directory."""
    path = directory / name
    try:
        inside = path.resolve().is_relative_to(directory.resolve())
    except (RuntimeError, OSError):  # a symbolic-link loop (RuntimeError before Python 3.13)
        raise DatasetError(f"{name} is a symbolic-link loop") from None
    if not inside:
        raise DatasetError(f"{name} leads outside the dataset directory")
    return path


def read_header(directory: str | Path) -> DatasetHeader:
    """The manifest's header (robot, tool, surface, control period), without reading a trial."""
    return parse_header(load_manifest(Path(directory) / MANIFEST))


def read_trial(directory: Path, entry: TrialEntry, robot: str = "panda") -> TrialLog:
    """The log of the trial ``entry`` of a dataset of ``robot``."""
    table = _read_table(_inside(directory, entry.file), trial_columns(robot))
    joints = 1 + len(base_columns(robot))
    t, q, dq, tau, dq_cmd = (table[:, 0], *np.split(table[:, joints:], 4, axis=1))
    base = table[:, 1:joints] if joints > 1 else np.zeros((0, len(BASE_COLUMNS)))
    log = TrialLog(t, q, dq, tau, dq_cmd, base=base)
    if entry.force_file is not None:
        force = _read_table(_inside(directory, entry.force_file), FORCE_COLUMNS)
        log.force_t, log.force = force[:, 0], force[:, 1:]
    return log


def read_dataset(
    directory: str | Path, skip: frozenset[str] | set[str] = frozenset(), strict: bool = True
) -> Dataset:
    """Read a dataset, leaving out the trials whose ids are in ``skip``; raises
    :class:`DatasetError` on the first problem (see :func:`validate`). With ``strict=False`` a trial
    entry that cannot be parsed is left out too (:func:`validate` reports it)."""
    directory = Path(directory)
    manifest = load_manifest(directory / MANIFEST)
    header = parse_header(manifest)
    trials = []
    for raw in manifest["trials"]:
        try:
            entry = parse_entry(raw, header.surface.normal)
        except DatasetError:
            if strict:
                raise
            continue
        if entry.id in skip:
            continue
        try:
            trials.append(DatasetTrial(entry, read_trial(directory, entry, header.robot)))
        except DatasetError as error:
            raise DatasetError(f"trial {entry.id!r}: {error}") from None
    return Dataset(directory, header, trials)
