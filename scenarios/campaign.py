"""The paper's experimental campaign (Sec. VI) in simulation: dataset, Table I and figures.

Trials: every posture x every normal speed (paper: 0.08, 0.10, 0.12, 0.15, 0.18 m/s), plus the
tangential series on the first posture (paper: v_t = 0.03 .. 0.12 m/s at v_n = 0.12 m/s) along the
surface tangent t = normalise(n x e_z) of ``sim.generation`` (+y for the default wall). Each
trial is one ``scenarios.trial`` run with the jump-aware constraints off, so that the tool hits at
the requested speed, as in the paper. The simulation is deterministic: one trial per setting
stands for the paper's ten repeats.

Table I: for each trial and predictor, the average prediction error (26)
e = (1/n) sum_i |dq*_i - dq°_i| (n joints) of the predictor's own jump at the pre-impact state against the
simulated jump dq°, and the reduction 100 (1 - e_crb / e_classical) % of CRB against the classical
prediction (the paper's 81.98 %); the last row averages every trial.

Figures (PNG): per posture, the simulated jump of every joint against the normal speed (like the
paper's Fig. 8) and the absolute error |e_i| of every predictor of Table I per joint (Figs. 9-11),
each kind on one y scale for all postures; for the tangential series, the average error of
every predictor against v_t (Fig. 12).

Output directory: the dataset (``controller.measured.dataset``: ``dataset.json`` and one CSV pair per trial),
``table1.json``, ``table1.txt`` and the figures; every file written atomically.

One :class:`Campaign` runs every robot: it is given the robot's trial runner (a
:class:`CampaignTrials`: :class:`FixedBaseTrials` above for an arm, the closed-loop trials of
``scenarios.trial``; ``scenarios.humanoid_campaign.FloatingBaseTrials`` for a floating base,
whose postures are its stances and whose Table I is ``table1.json`` and ``table1.md``), writes
each trial to the dataset as it comes, then the runner's Table I (its files and figures).
"""

from __future__ import annotations

import json
from contextlib import closing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from impactqp.controller.model.jump import METHODS, average_prediction_error  # noqa: E402
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice  # noqa: E402
from impactqp.controller.model.postures import Surface  # noqa: E402
from impactqp.controller.measured.atomic import write_atomic, write_text_atomic  # noqa: E402
from impactqp.sim.generation import DEFAULT_SPEEDS, TANGENTIAL_SERIES_NORMAL_SPEED, tangential_direction  # noqa: E402
from impactqp.controller.measured.dataset import DatasetHeader, DatasetWriter, TrialEntry  # noqa: E402
from impactqp.controller.measured.trial_log import TrialLog  # noqa: E402
from impactqp.controller.model.robot_description import RobotDescription  # noqa: E402
from impactqp.sim.plant import PlantParameters  # noqa: E402
from impactqp.sim.generation import dataset_header  # noqa: E402

from impactqp.sim.runner import TrialSpec  # noqa: E402

from .trial import TrialPool, TrialResult  # noqa: E402
from impactqp.controller.model.validation import BadInputError, approach_speed  # noqa: E402

PAPER_SPEEDS = DEFAULT_SPEEDS
PAPER_TANGENTIAL_SPEEDS = tuple(round(0.03 + 0.01 * i, 2) for i in range(10))
TANGENTIAL_NORMAL_SPEED = TANGENTIAL_SERIES_NORMAL_SPEED


def dataset_trial(result: TrialResult) -> tuple[TrialEntry, TrialLog]:
    """The manifest entry and the log (control-rate CSV and force CSV) of one simulated trial."""
    spec = result.spec
    trial_id = spec.trial_id
    entry = TrialEntry(
        id=trial_id,
        file=f"{trial_id}.csv",
        reference_normal_speed=spec.normal_speed,
        force_file=f"{trial_id}_force.csv",
        reference_tangential_velocity=tuple(float(v) for v in spec.tangential_velocity),
        posture=spec.posture,
        impact_time=result.impact.t_contact_start,
    )
    return entry, result.log


def write_trial(writer: DatasetWriter, result: TrialResult) -> None:
    """Add one simulated trial to a dataset."""
    writer.add_trial(*dataset_trial(result))


def named_postures(robot: RobotDescription) -> Mapping:
    """The postures a campaign of ``robot`` may run: a floating base's stances, a fixed base's
    named impact postures (its description's)."""
    return robot.stances if robot.floating else robot.postures


def check_postures(robot: RobotDescription, names) -> tuple[str, ...]:
    """``names`` (None: every named posture of ``robot``) as a tuple, each checked."""
    known = named_postures(robot)
    names = tuple(known) if names is None else tuple(names)
    for name in names:
        if name not in known:
            raise BadInputError(f"unknown posture {name!r} for the {robot.name}; known: {', '.join(known)}")
    return names


@dataclass(frozen=True)
class CampaignPlan:
    """Which trials the campaign runs (module docstring); ``postures`` None: every named posture
    of the robot (a floating base's: its stances)."""

    postures: tuple[str, ...] | None = None
    speeds: tuple[float, ...] = PAPER_SPEEDS
    tangential_speeds: tuple[float, ...] = PAPER_TANGENTIAL_SPEEDS
    tangential_normal_speed: float = TANGENTIAL_NORMAL_SPEED

    def __post_init__(self):
        if self.postures is not None and not self.postures:
            raise BadInputError("the campaign needs at least one posture")
        if not self.speeds:
            raise BadInputError("the campaign needs at least one speed")
        for v in self.speeds:
            approach_speed(v, "every normal speed")
        for v in self.tangential_speeds:
            approach_speed(abs(v) if v else 1.0, "every tangential speed")

    def specs(self, surface: Surface, choice: RobotChoice = DEFAULT_CHOICE) -> list[TrialSpec]:
        """The trials, at ``choice``'s named postures (solved for its tool); bad input for a
        posture the robot does not have."""
        postures = check_postures(choice.robot, self.postures)
        specs = [
            TrialSpec(name, choice.posture(name).q, float(speed))
            for name in postures
            for speed in self.speeds
        ]
        tangent = tangential_direction(surface.normal)
        first = postures[0]
        specs += [
            TrialSpec(first, choice.posture(first).q, self.tangential_normal_speed, float(v_t) * tangent)
            for v_t in self.tangential_speeds
        ]
        return specs


@dataclass(frozen=True)
class TableRow:
    """One trial of Table I: its setting, the contact speed and the error (26) per predictor."""

    trial_id: str
    posture: str
    normal_speed: float
    tangential_speed: float
    contact_speed: float
    errors: dict[str, float]
    measured_jump: np.ndarray = field(repr=False)
    joint_errors: dict[str, np.ndarray] = field(repr=False)

    @classmethod
    def of(cls, result: TrialResult) -> TableRow:
        measured = result.impact.dq_jump
        return cls(
            trial_id=result.spec.trial_id,
            posture=result.spec.posture,
            normal_speed=result.spec.normal_speed,
            tangential_speed=float(np.linalg.norm(result.spec.tangential_velocity)),
            contact_speed=result.contact_speed,
            errors={m: float(average_prediction_error(result.predicted[m], measured)) for m in METHODS},
            measured_jump=measured,
            joint_errors={m: np.abs(result.predicted[m] - measured) for m in METHODS},
        )

    @property
    def crb_reduction(self) -> float:
        """100 (1 - e_crb / e_classical): how much CRB cuts the classical error, in %."""
        return 100.0 * (1.0 - self.errors["crb"] / self.errors["classical"])

    def to_json(self) -> dict:
        return {
            "trial": self.trial_id,
            "posture": self.posture,
            "normal_speed": self.normal_speed,
            "tangential_speed": self.tangential_speed,
            "contact_speed": self.contact_speed,
            "average_error": self.errors,
            "crb_reduction_percent": self.crb_reduction,
            "measured_jump": self.measured_jump.tolist(),
        }


@dataclass(frozen=True)
class Table1:
    rows: list[TableRow]

    def mean_errors(self) -> dict[str, float]:
        return {m: float(np.mean([r.errors[m] for r in self.rows])) for m in METHODS}

    def mean_crb_reduction(self) -> float:
        mean = self.mean_errors()
        return 100.0 * (1.0 - mean["crb"] / mean["classical"])

    def to_json(self) -> dict:
        return {
            "methods": list(METHODS),
            "rows": [r.to_json() for r in self.rows],
            "mean_average_error": self.mean_errors(),
            "mean_crb_reduction_percent": self.mean_crb_reduction(),
        }

    def files(self) -> dict[str, str]:
        """The table's files by name: its JSON and its text."""
        return {"table1.json": json.dumps(self.to_json(), indent=2) + "\n", "table1.txt": self.text() + "\n"}

    def write_figures(self, out: Path) -> list[Path]:
        return CampaignFigures(self).write(out)

    def text(self) -> str:
        """The table as aligned text (rad/s; the last column in %)."""
        head = f"{'posture':<12}{'v_n':>6}{'v_t':>6}{'v_c':>8}" + "".join(f"{m:>17}" for m in METHODS)
        lines = [
            "Table I (simulation): average prediction error (26), rad/s",
            head + f"{'crb vs classical':>18}",
        ]
        for r in self.rows:
            lines.append(
                f"{r.posture:<12}{r.normal_speed:6.3f}{r.tangential_speed:6.3f}{r.contact_speed:8.4f}"
                + "".join(f"{r.errors[m]:17.4f}" for m in METHODS)
                + f"{r.crb_reduction:16.1f} %"
            )
        mean = self.mean_errors()
        lines.append(
            f"{'all trials':<32}" + "".join(f"{mean[m]:17.4f}" for m in METHODS)
            + f"{self.mean_crb_reduction():16.1f} %"
        )
        return "\n".join(lines)


class CampaignTable(Protocol):
    """A campaign's Table I: its JSON, its text, its files by name and its figures."""

    def to_json(self) -> dict: ...

    def text(self) -> str: ...

    def files(self) -> dict[str, str]: ...

    def write_figures(self, out: Path) -> list[Path]: ...


class CampaignTrials(Protocol):
    """The trial runner of one robot that a :class:`Campaign` is given: its dataset's header, the
    tasks of a plan, their results (in the tasks' order), each result as a dataset trial, and the
    Table I of the results."""

    @property
    def header(self) -> DatasetHeader: ...

    def tasks(self, plan: CampaignPlan) -> list: ...

    def results(self, tasks: list, jobs: int) -> Iterator[Any]: ...

    def dataset_trial(self, result: Any) -> tuple[TrialEntry, TrialLog]: ...

    def table(self, results: list) -> CampaignTable: ...


@dataclass(frozen=True)
class FixedBaseTrials:
    """The campaign's trials of a fixed-base arm (module docstring): ``scenarios.trial`` runs on
    ``surface`` and ``plant`` (None: the default plant) with ``choice``'s robot and tool."""

    surface: Surface
    plant: PlantParameters | None = None
    choice: RobotChoice = DEFAULT_CHOICE

    @property
    def header(self) -> DatasetHeader:
        return dataset_header(self.surface, self.choice)

    def tasks(self, plan: CampaignPlan) -> list[TrialSpec]:
        return plan.specs(self.surface, self.choice)

    def results(self, tasks: list[TrialSpec], jobs: int) -> Iterator[TrialResult]:
        with TrialPool(self.surface, self.plant, jobs, self.choice) as pool:
            yield from pool.map(tasks)

    def dataset_trial(self, result: TrialResult) -> tuple[TrialEntry, TrialLog]:
        return dataset_trial(result)

    def table(self, results: list[TrialResult]) -> Table1:
        return Table1([TableRow.of(result) for result in results])


class Campaign:
    """Runs a :class:`CampaignPlan` with the trial runner ``trials`` of one robot
    (:class:`CampaignTrials`) on ``jobs`` worker processes and writes its outputs."""

    def __init__(self, plan: CampaignPlan, trials: CampaignTrials, *, jobs: int = 1, progress: bool = False):
        self.plan = plan
        self.trials = trials
        self.jobs = jobs
        self.progress = progress

    def run(self, out: str | Path) -> CampaignTable:
        """Run every trial, adding each to the dataset in ``out`` as it comes, then write Table I's
        files and figures there; an existing dataset of another header is refused first."""
        out = Path(out)
        writer = DatasetWriter(out, self.trials.header)
        tasks = self.trials.tasks(self.plan)
        results = []
        with closing(self.trials.results(tasks, self.jobs)) as running:  # its pool ends with the loop
            for result in tqdm(running, total=len(tasks), desc="campaign", unit="trial", disable=not self.progress):
                writer.add_trial(*self.trials.dataset_trial(result))
                results.append(result)
        table = self.trials.table(results)
        for name, text in table.files().items():
            write_text_atomic(out / name, text)
        table.write_figures(out)
        return table


class CampaignFigures:
    """The PNG figures of the module docstring. Each point is one simulated trial (one per
    setting, the simulation is deterministic); the figures of the postures share their y scale so
    that they compare, and the error panels show every predictor of Table I."""

    def __init__(self, table: Table1):
        self.table = table

    def write(self, out: Path) -> list[Path]:
        paths = []
        normal_rows = [r for r in self.table.rows if r.tangential_speed == 0.0]
        jump_limits = y_limits([r.measured_jump for r in normal_rows])
        error_limits = y_limits([r.joint_errors[m] for r in normal_rows for m in METHODS], zero=True)
        for posture in dict.fromkeys(r.posture for r in normal_rows):
            rows = sorted((r for r in normal_rows if r.posture == posture), key=lambda r: r.normal_speed)
            jumps = self.jumps_figure(posture, rows, jump_limits)
            paths.append(save_figure(jumps, out / f"jumps_{posture}.png"))
            paths.append(save_figure(self.errors_figure(posture, rows, error_limits), out / f"errors_{posture}.png"))
        tangential = sorted((r for r in self.table.rows if r.tangential_speed > 0.0), key=lambda r: r.tangential_speed)
        if tangential:
            paths.append(save_figure(self.tangential_figure(tangential), out / "tangential.png"))
        return paths

    @staticmethod
    def jumps_figure(posture: str, rows: list[TableRow], ylim: tuple[float, float] | None = None):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.normal_speed for r in rows]
        jumps = np.array([r.measured_jump for r in rows])
        for j in range(jumps.shape[1]):
            ax.plot(speeds, jumps[:, j], "o-", label=f"joint {j + 1}")
        ax.set(
            xlabel="normal contact speed (m/s)", ylabel="simulated jump dq+ - dq- (rad/s)",
            title=f"Simulated joint-velocity jumps at {posture}\n(one trial per speed, no tangential velocity)",
        )
        if ylim is not None:
            ax.set_ylim(ylim)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        return fig

    @staticmethod
    def errors_figure(posture: str, rows: list[TableRow], ylim: tuple[float, float] | None = None):
        fig, axes = plt.subplots(1, len(METHODS), figsize=(3.6 * len(METHODS), 4.0), sharey=True)
        speeds = [r.normal_speed for r in rows]
        for ax, method in zip(axes, METHODS):
            errors = np.array([r.joint_errors[method] for r in rows])
            for j in range(errors.shape[1]):
                ax.plot(speeds, errors[:, j], "o-", label=f"joint {j + 1}")
            ax.set(title=method, xlabel="normal contact speed (m/s)", ylabel="|e_i|, eq. (25) (rad/s)")
            ax.yaxis.set_tick_params(labelleft=True)
        if ylim is not None:
            axes[0].set_ylim(ylim)
        axes[-1].legend(fontsize=7, ncol=2)
        fig.suptitle(
            f"Absolute prediction error per joint at {posture}: each predictor's own jump against the "
            "simulated one (one trial per speed)", fontsize=10,
        )
        fig.tight_layout()
        return fig

    @staticmethod
    def tangential_figure(rows: list[TableRow]):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.tangential_speed for r in rows]
        for method in METHODS:
            ax.plot(speeds, [r.errors[method] for r in rows], "o-", label=method)
        ax.set(
            xlabel="tangential speed v_t (m/s)", ylabel="average prediction error, eq. (26) (rad/s)",
            title=f"Tangential series at {rows[0].posture}, v_n = {rows[0].normal_speed:g} m/s\n"
            f"(error averaged over the {len(rows[0].measured_jump)} joints, one trial per v_t)",
        )
        ax.set_ylim(bottom=0.0)
        ax.legend()
        fig.tight_layout()
        return fig


def y_limits(values: list[np.ndarray], zero: bool = False) -> tuple[float, float] | None:
    """A y range that holds every value (and 0 when ``zero``), with a 5 % margin; None without
    values."""
    if not values:
        return None
    data = np.concatenate([np.ravel(v) for v in values] + ([np.zeros(1)] if zero else []))
    low, high = float(data.min()), float(data.max())
    margin = 0.05 * (high - low) or 0.05
    return (0.0 if zero else low - margin, high + margin)


def save_figure(fig, path: Path) -> Path:
    """Save a figure as PNG atomically (``controller.measured.atomic.write_atomic``) and close it."""
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    finally:
        plt.close(fig)
