"""Real robot logs: libfranka's ``franka::logToCSV`` files turned into an impact dataset
(``impactqp dataset import-franka``; dataset format in ``docs/dataset.md``).

The CSV format (libfranka ``src/log.cpp``): one header line, then one line per control cycle.
The header names are ``time, success_rate``, then per array ``name[0], ..., name[N-1]``, with n
the joints of the arm (the robot the dataset names)::

    state.q[n]  state.q_d[n]  state.dq[n]  state.dq_d[n]  state.tau_J[n]
    state.tau_ext_hat_filtered[n]
    cmd.q_d[n]  cmd.dq_d[n]  cmd.O_T_EE_d[16]  cmd.O_dP_EE_d[6]  cmd.tau_J_d[n]

24 + 9 n columns in all. Older libfranka separates header names by ", ", newer by ","; both are read
(values are always separated by ","). ``time`` is the robot's clock in milliseconds.

One row holds the robot state of cycle n+1 and the command of cycle n (libfranka's
``franka::Record``). The dataset's ``dq_cmd[k]`` is the command applied after the state k was
measured, so it is the ``cmd.dq_d`` of the *next* row. The dataset's ``tau[k]`` is the joint
torque applied over period k (``docs/dataset.md``), which the robot measures at the end of that
period: the ``state.tau_J`` of the next row as well. The last row, whose following row is not
logged, is dropped. Mapping: ``t = (time - time[0]) / 1000`` (s), ``q = state.q``,
``dq = state.dq`` (row k), ``tau = state.tau_J`` and ``dq_cmd = cmd.dq_d`` (row k + 1).

The dataset's control period is the median step of the logged clock, rounded to the clock's
logged resolution (``logged_period``: a 1 ms clock gives 0.001 s). A log does not know the
surface's friction coefficient, so the manifest leaves ``surface.friction`` out (readers then
take the default of ``controller.model.postures.Surface``).

One log is one trial. Without a given reference speed, it is estimated from the log: the
impact is detected from the torque residual (``controller.measured.impact``, no force sensor),
and the reference velocity is the commanded velocity of the contact point, v = J(q) dq_cmd,
averaged over the ``REFERENCE_WINDOW`` cycles that end ``REFERENCE_GAP`` cycles before the
detected impact (the measured dq when every command is zero, e.g. under torque control). Its
component along -n is the reference normal speed; the rest is the reference tangential
velocity. Both are rounded to ``REFERENCE_ROUNDING`` m/s so that repeated trials share a
condition. A trial whose impact configuration is within ``POSTURE_TOLERANCE`` rad (every joint)
of a named posture is labelled with it.

Bad or foreign files raise :class:`BadInputError` with one line naming the file; every log is
read and checked before anything is written, and the logs are only read.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.files import regular_file
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError, approach_speed

from .dataset import DatasetError, DatasetHeader, TrialEntry
from .dataset_writer import DatasetWriter
from .impact import ImpactNotFoundError, measure_impact
from .trial_log import TrialLog

def franka_arrays(joints: int) -> tuple[tuple[str, int], ...]:
    """The arrays of a logToCSV file of an arm of ``joints`` joints and their sizes (module
    docstring)."""
    return (
        ("state.q", joints),
        ("state.q_d", joints),
        ("state.dq", joints),
        ("state.dq_d", joints),
        ("state.tau_J", joints),
        ("state.tau_ext_hat_filtered", joints),
        ("cmd.q_d", joints),
        ("cmd.dq_d", joints),
        ("cmd.O_T_EE_d", 16),
        ("cmd.O_dP_EE_d", 6),
        ("cmd.tau_J_d", joints),
    )


def franka_columns(joints: int) -> tuple[str, ...]:
    """The header names of a logToCSV file of an arm of ``joints`` joints."""
    arrays = franka_arrays(joints)
    return ("time", "success_rate") + tuple(f"{name}[{i}]" for name, size in arrays for i in range(size))


MIN_ROWS = 50
REFERENCE_WINDOW = 20
REFERENCE_GAP = 3
REFERENCE_ROUNDING = 1e-3
POSTURE_TOLERANCE = 0.1
MAX_TIME_DECIMALS = 6  # the clock (ms) is logged to at most a nanosecond
_INDEXED = re.compile(r"^(?P<name>[A-Za-z_.]+)\[(?P<index>\d+)\]$")


@dataclass(frozen=True)
class FrankaTrial:
    """One imported log: the trial arrays and the reference velocity of its approach."""

    source: Path
    log: TrialLog
    reference_normal_speed: float
    reference_tangential_velocity: tuple[float, float, float]
    posture: str | None
    impact_time: float | None
    control_period: float


def _columns(path: Path, header: str, joints: int) -> dict[str, int]:
    names = [name.strip() for name in header.split(",")]
    expected = franka_columns(joints)
    if tuple(names) != expected:
        missing = [c for c in expected if c not in names]
        if names[:2] != ["time", "success_rate"] or not all(_INDEXED.match(n) for n in names[2:]):
            raise BadInputError(
                f"{path}: not a libfranka logToCSV file (the header must start with 'time, success_rate, "
                f"state.q[0]'; got {header[:60]!r})"
            )
        if missing:
            raise BadInputError(
                f"{path}: libfranka log lacks the column(s) {', '.join(missing[:3])}"
                + (f" and {len(missing) - 3} more" if len(missing) > 3 else "")
            )
    return {name: i for i, name in enumerate(names)}


def read_franka_csv(path: str | Path, joints: int) -> dict[str, np.ndarray]:
    """The columns of a ``franka::logToCSV`` file of an arm of ``joints`` joints: ``time`` (ms)
    and one (rows, size) array per logged array name (e.g. ``"state.q"``). Raises
    :class:`BadInputError` for a missing, empty, foreign, truncated or non-numeric file."""
    path = Path(path)
    if not path.exists():
        raise BadInputError(f"{path}: no such libfranka log")
    regular_file(path, "the libfranka log")  # never open a FIFO or a device: it could block
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as error:
        raise BadInputError(f"{path}: cannot be read as a libfranka log ({error.__class__.__name__})") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise BadInputError(f"{path}: empty file, not a libfranka log")
    index = _columns(path, lines[0], joints)
    if not text.endswith("\n"):
        raise BadInputError(f"{path}: the last line is incomplete (libfranka ends every line): truncated file")
    rows = [line for line in lines[1:] if line.strip()]
    table = np.empty((len(rows), len(index)))
    for k, line in enumerate(rows):
        cells = line.split(",")
        if len(cells) != len(index):
            raise BadInputError(
                f"{path}: line {k + 2} has {len(cells)} values, the header {len(index)} (truncated file?)"
            )
        try:
            table[k] = [float(c) for c in cells]
        except ValueError:
            raise BadInputError(f"{path}: line {k + 2} holds a value that is not a number") from None
    if len(rows) < MIN_ROWS:
        raise BadInputError(f"{path}: only {len(rows)} samples; an impact trial needs at least {MIN_ROWS}")
    if not np.all(np.isfinite(table)):
        k = int(np.argwhere(~np.isfinite(table))[0, 0])
        raise BadInputError(f"{path}: line {k + 2} holds a NaN or infinite value")
    columns = {"time": table[:, index["time"]]}
    for name, size in franka_arrays(joints):
        columns[name] = table[:, [index[f"{name}[{i}]"] for i in range(size)]]
    return columns


def trial_log_of(path: str | Path, columns: dict[str, np.ndarray]) -> TrialLog:
    """The dataset's arrays of one libfranka log (mapping in the module docstring)."""
    time = columns["time"]
    if np.any(np.diff(time) <= 0.0):
        k = int(np.argmax(np.diff(time) <= 0.0))
        raise BadInputError(f"{path}: time does not increase at line {k + 3}")
    return TrialLog(
        t=(time[:-1] - time[0]) / 1000.0,
        q=columns["state.q"][:-1].copy(),
        dq=columns["state.dq"][:-1].copy(),
        tau=columns["state.tau_J"][1:].copy(),
        dq_cmd=columns["cmd.dq_d"][1:].copy(),
    )


def logged_period(time_ms: np.ndarray) -> float:
    """The control period (s) of a log whose clock ``time_ms`` is in ms: the median step rounded
    to the clock's logged resolution, the fewest decimals (at most ``MAX_TIME_DECIMALS``) that
    write every time stamp, so that the division by 1000 adds no binary rounding error."""
    exact = 10.0**-MAX_TIME_DECIMALS
    decimals = next(
        (d for d in range(MAX_TIME_DECIMALS) if np.all(np.abs(time_ms - np.round(time_ms, d)) <= exact)),
        MAX_TIME_DECIMALS,
    )
    step = round(float(np.median(np.diff(time_ms))), decimals)
    return round(step / 1000.0, decimals + 3)


def contact_velocity(robot: RobotModel, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """World velocity (m/s) of the tool's contact point at the state (q, dq)."""
    model, data = robot.model, robot.data
    pin.forwardKinematics(model, data, q, dq)
    return pin.getFrameVelocity(model, data, robot.contact_frame_id, pin.LOCAL_WORLD_ALIGNED).linear.copy()


def nearest_posture(q: np.ndarray, choice: RobotChoice = DEFAULT_CHOICE) -> str | None:
    """The named posture of ``choice`` within ``POSTURE_TOLERANCE`` of q, if any."""
    for name, posture in choice.postures.items():
        if np.max(np.abs(q - posture.q)) <= POSTURE_TOLERANCE:
            return name
    return None


def import_trial(
    path: str | Path,
    surface: Surface,
    *,
    choice: RobotChoice = DEFAULT_CHOICE,
    robot: RobotModel | None = None,
    reference_speed: float | None = None,
) -> FrankaTrial:
    """Read one libfranka log of ``choice``'s robot and tool (``robot``: its model, built when
    None) and estimate its reference velocity (module docstring)."""
    path = Path(path)
    robot = choice.model() if robot is None else robot
    columns = read_franka_csv(path, len(choice.robot.joints))
    log = trial_log_of(path, columns)
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError as error:
        if reference_speed is None:
            raise BadInputError(f"{path}: no impact found ({error}); give --reference-speed to import it anyway") from None
        impact = None
    tangential = np.zeros(3)
    speed = reference_speed
    if impact is not None:
        last = max(impact.pre_index - REFERENCE_GAP, 1)
        first = max(last - REFERENCE_WINDOW, 0)
        dq = log.dq_cmd if np.any(log.dq_cmd[first:last] != 0.0) else log.dq
        velocity = np.mean([contact_velocity(robot, log.q[k], dq[k]) for k in range(first, last)], axis=0)
        normal_speed = float(-surface.normal @ velocity)
        tangential = velocity + normal_speed * surface.normal
        tangential = np.round(tangential / REFERENCE_ROUNDING) * REFERENCE_ROUNDING + 0.0
        if speed is None:
            speed = round(normal_speed / REFERENCE_ROUNDING) * REFERENCE_ROUNDING
            if not speed > 0.0:
                raise BadInputError(
                    f"{path}: the contact point does not approach the surface before the impact "
                    f"(normal speed {normal_speed:+.4f} m/s); check --surface-normal or give --reference-speed"
                )
    return FrankaTrial(
        source=path,
        log=log,
        reference_normal_speed=float(speed),
        reference_tangential_velocity=tuple(float(x) for x in tangential),
        posture=nearest_posture(log.q[impact.pre_index], choice) if impact is not None else None,
        impact_time=float(log.t[impact.pre_index]) if impact is not None else None,
        control_period=logged_period(columns["time"]),
    )


def _trial_ids(paths: list[Path]) -> list[str]:
    ids: list[str] = []
    for path in paths:
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", path.stem) or "log"
        name, k = stem, 1
        while name in ids:
            k += 1
            name = f"{stem}_{k}"
        ids.append(name)
    return ids


def import_franka_logs(
    out: str | Path,
    logs: list[str | Path],
    surface: Surface,
    *,
    choice: RobotChoice = DEFAULT_CHOICE,
    reference_speed: float | None = None,
) -> list[TrialEntry]:
    """Write the libfranka logs ``logs`` of ``choice``'s robot and tool as a dataset in ``out``
    (one trial per log; the manifest records the robot and the tool) and return the trial
    entries. Every log is read and checked before the first file is written."""
    if not logs:
        raise BadInputError("give at least one libfranka log")
    if reference_speed is not None:
        approach_speed(reference_speed, "--reference-speed")
    robot = choice.model()
    paths = [Path(p) for p in logs]
    trials = [import_trial(p, surface, choice=choice, robot=robot, reference_speed=reference_speed) for p in paths]
    periods = [t.control_period for t in trials]
    if np.ptp(periods) > 1e-6:
        raise BadInputError(f"the logs have different control periods: {sorted(set(np.round(periods, 6)))} s")
    header = DatasetHeader(
        tool=choice.tool, surface=surface, control_period=float(periods[0]), robot=choice.robot.name,
        friction_known=False,
    )
    Path(out).mkdir(parents=True, exist_ok=True)
    try:
        writer = DatasetWriter(out, header)
        entries = []
        for trial_id, trial in zip(_trial_ids(paths), trials):
            entry = TrialEntry(
                id=trial_id,
                file=f"{trial_id}.csv",
                reference_normal_speed=trial.reference_normal_speed,
                reference_tangential_velocity=trial.reference_tangential_velocity,
                posture=trial.posture,
                impact_time=trial.impact_time,
            )
            writer.add_trial(entry, trial.log)
            entries.append(entry)
    except DatasetError as error:
        raise BadInputError(str(error)) from None
    return entries
