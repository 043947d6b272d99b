"""Table I of a campaign (Sec. VI), one table for every robot: per trial its setting, the contact
speed and the average prediction error (26) e = (1/n) sum_i |dq*_i - dq°_i| over the n joints of
each predictor's jump against the simulated one, and the reduction 100 (1 - e_crb / e_classical) %
of CRB against the classical prediction (the paper's 81.98 %; negative when CRB is worse); the
last row averages every trial.

What a robot's table shows is data chosen by its description (:class:`TableLayout`): a fixed-base
arm's (:data:`ARM_TABLE`) the setting v_n, v_t, v_c and every predictor of
``controller.model.jump`` in aligned text, with its figures (``scenarios.campaign_figures``); a
robot with held contacts' (:func:`held_contact_table`) the measured contact speed, the normal
impulse, the CoM velocity jump, the foot slip and lift, whether the robot fell, and the
held-contact predictors with the feet-held momentum law (``momentum``, fed the measured impulse)
in a Markdown table, no figures; its JSON names the robot, numbers its rows and carries each
trial's own report (``sim.trial_result.TrialResult.to_json``, but its predictions).

Every robot's table is written as the same two files (:data:`TABLE_FILES`): ``table1.json`` and
the Markdown ``table1.md`` (an arm's aligned text inside it as a fenced ``text`` block).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS
from impactqp.controller.model.robot_description import RobotDescription
from impactqp.sim.trial_result import TrialResult


HELD_CONTACT_PREDICTORS = (*HELD_CONTACT_METHODS, "momentum")
"""The predictors a robot with held contacts' table shows: its methods and the momentum law."""
TABLE_FILES = ("table1.json", "table1.md")
"""The files of every robot's Table I: its JSON and its Markdown."""
UNREPORTED = ("predicted", "predicted_com_jump", "robot")
"""The keys of a trial's report that its row of Table I's JSON leaves out."""


def crb_reduction(errors: dict[str, float]) -> float:
    """100 (1 - e_crb / e_classical) %: how much CRB cuts the classical error (negative: worse)."""
    return 100.0 * (1.0 - errors["crb"] / errors["classical"])


@dataclass(frozen=True)
class TableRow:
    """One trial of Table I: its setting, the contact speed and the error (26) per predictor; the
    measured jump (nv), each predictor's |error| per joint and its jump of the joints (the
    figures'); ``report`` the trial's own JSON (without its predictions) when the table carries
    it, else empty."""

    trial_id: str
    posture: str
    normal_speed: float
    tangential_speed: float
    contact_speed: float
    errors: dict[str, float]
    measured_jump: np.ndarray = field(repr=False)
    joint_errors: dict[str, np.ndarray] = field(repr=False)
    report: dict = field(default_factory=dict, repr=False)
    predicted_jump: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, result: TrialResult, report: bool = False) -> TableRow:
        """The row of ``result``, with its report (``report``) or not."""
        joints = slice(len(result.measured_jump) - result.log.q.shape[1], None)
        measured = result.measured_jump
        return cls(
            trial_id=result.trial_id,
            posture=result.posture,
            normal_speed=result.normal_speed,
            tangential_speed=float(np.linalg.norm(result.tangential_velocity)),
            contact_speed=result.contact_speed,
            errors=result.errors,
            measured_jump=measured,
            joint_errors={m: np.abs(dv[joints] - measured[joints]) for m, dv in result.predicted.items()},
            report={k: v for k, v in result.to_json().items() if k not in UNREPORTED} if report else {},
            predicted_jump={m: dv[joints].copy() for m, dv in result.predicted.items()},
        )

    @property
    def crb_reduction(self) -> float:
        """How much CRB cuts the classical error, in % (:func:`crb_reduction`)."""
        return crb_reduction(self.errors)

    def to_json(self, trial: str | int | None = None) -> dict:
        """The row's JSON: its report's keys, then the row's (``trial``: the row's name in the
        table, None: its trial id)."""
        return {
            **self.report,
            "trial": self.trial_id if trial is None else trial,
            "posture": self.posture,
            "normal_speed": self.normal_speed,
            "tangential_speed": self.tangential_speed,
            "contact_speed": self.contact_speed,
            "average_error": self.errors,
            "crb_reduction_percent": self.crb_reduction,
            "measured_jump": self.measured_jump.tolist(),
        }


@dataclass(frozen=True)
class Column:
    """One setting column of Table I's text: its header, its cell of a row, the cell's format
    and, in aligned text, its width and alignment."""

    header: str
    cell: Callable[[TableRow], object]
    spec: str
    width: int = 0
    align: str = ">"


@dataclass(frozen=True)
class TableLayout:
    """What a robot's Table I shows (module docstring): the setting ``columns`` of its text, the
    predictors its JSON averages (``methods``) and its text shows (``shown``), whether its text is
    a Markdown table (``markdown``; else aligned text), whether it has figures; a table of a named
    ``robot`` (None: an arm's) names it in its JSON, numbers its rows and carries each trial's
    report."""

    columns: tuple[Column, ...]
    methods: tuple[str, ...]
    shown: tuple[str, ...]
    markdown: bool
    figures: bool
    robot: str | None = None


ARM_TABLE = TableLayout(
    columns=(
        Column("posture", lambda r: r.posture, "", 12, "<"),
        Column("v_n", lambda r: r.normal_speed, ".3f", 6),
        Column("v_t", lambda r: r.tangential_speed, ".3f", 6),
        Column("v_c", lambda r: r.contact_speed, ".4f", 8),
    ),
    methods=METHODS, shown=METHODS, markdown=False, figures=True,
)
"""A fixed-base arm's Table I (module docstring)."""

HELD_CONTACT_COLUMNS = (
    Column("stance", lambda r: r.posture, ""),
    Column("v cmd (m/s)", lambda r: r.normal_speed, ".2f"),
    Column("v contact (m/s)", lambda r: r.contact_speed, ".3f"),
    Column("impulse n (N s)", lambda r: -r.report["impulse"][0], ".3f"),
    Column("CoM jump x (m/s)", lambda r: r.report["com_jump"][0], ".4f"),
    Column("slip (mm)", lambda r: 1e3 * r.report["foot_slip"], ".2f"),
    Column("lift (mm)", lambda r: 1e3 * r.report["foot_lift"], ".2f"),
    Column("fell", lambda r: "yes" if r.report["fell"] else "no", ""),
)


def held_contact_table(robot: str) -> TableLayout:
    """The Table I of the robot with held contacts named ``robot`` (module docstring; the wall's
    normal is -x: the normal impulse is -iota_x)."""
    return TableLayout(HELD_CONTACT_COLUMNS, HELD_CONTACT_METHODS, HELD_CONTACT_PREDICTORS, True, False, robot)


def table_layout(robot: RobotDescription) -> TableLayout:
    """The Table I of ``robot``: with held contacts :func:`held_contact_table`, else :data:`ARM_TABLE`."""
    return held_contact_table(robot.name) if robot.held_contacts else ARM_TABLE


@dataclass(frozen=True)
class Table1:
    """A campaign's Table I (module docstring): its rows in the ``layout`` of the robot."""

    rows: list[TableRow]
    layout: TableLayout = ARM_TABLE

    @classmethod
    def of(cls, robot: RobotDescription, results: list[TrialResult]) -> Table1:
        """The table of ``robot``'s trial results (:func:`table_layout`)."""
        layout = table_layout(robot)
        return cls([TableRow.of(result, layout.robot is not None) for result in results], layout)

    @property
    def figures(self) -> bool:
        return self.layout.figures

    def mean_errors(self, methods: tuple[str, ...] | None = None) -> dict[str, float]:
        """Eq. (26) averaged over the trials, per predictor of ``methods`` (None: the layout's)."""
        return {m: float(np.mean([r.errors[m] for r in self.rows])) for m in methods or self.layout.methods}

    def mean_crb_reduction(self) -> float:
        return crb_reduction(self.mean_errors())

    def to_json(self) -> dict:
        robot = self.layout.robot
        return {
            **({} if robot is None else {"robot": robot}),
            "methods": list(self.layout.methods),
            "rows": [r.to_json(None if robot is None else i) for i, r in enumerate(self.rows)],
            "mean_average_error": self.mean_errors(),
            "mean_crb_reduction_percent": self.mean_crb_reduction(),
        }

    def files(self) -> dict[str, str]:
        """The table's files by name (:data:`TABLE_FILES`): its JSON and its Markdown (the text;
        aligned text as a fenced block)."""
        text = self.text() if self.layout.markdown else f"```text\n{self.text()}\n```"
        return dict(zip(TABLE_FILES, (json.dumps(self.to_json(), indent=2, allow_nan=False) + "\n", text + "\n")))

    def write_figures(self, out: Path, subject: str = "") -> list[Path]:
        """The figures (``scenarios.campaign_figures``, their titles naming ``subject``: the robot
        and its tool) of a layout with figures, else none (matplotlib loads only then)."""
        if not self.figures:
            return []
        from .campaign_figures import CampaignFigures

        return CampaignFigures(self, subject).write(out)

    def text(self) -> str:
        """The table as text: a Markdown table or aligned text, as its layout says (errors in rad/s)."""
        return self._markdown() if self.layout.markdown else self._aligned()

    def _aligned(self) -> str:
        columns, shown = self.layout.columns, self.layout.shown
        lines = [
            "Table I (simulation): average prediction error (26), rad/s",
            "".join(f"{c.header:{c.align}{c.width}}" for c in columns) + "".join(f"{m:>17}" for m in shown)
            + f"{'crb vs classical':>18}",
        ]
        for r in self.rows:
            lines.append("".join(f"{c.cell(r):{c.align}{c.width}{c.spec}}" for c in columns)
                         + "".join(f"{r.errors[m]:17.4f}" for m in shown) + f"{r.crb_reduction:16.1f} %")
        mean = self.mean_errors(shown)
        lines.append(f"{'all trials':<{sum(c.width for c in columns)}}" + "".join(f"{mean[m]:17.4f}" for m in shown)
                     + f"{self.mean_crb_reduction():16.1f} %")
        return "\n".join(lines)

    def _markdown(self) -> str:
        columns, shown = self.layout.columns, self.layout.shown
        lines = ["| " + " | ".join([c.header for c in columns] + [f"e {m}" for m in shown]) + " |",
                 "|" + "---|" * (len(columns) + len(shown))]
        for r in self.rows:
            lines.append("| " + " | ".join([f"{c.cell(r):{c.spec}}" for c in columns]
                                           + [f"{r.errors[m]:.4f}" for m in shown]) + " |")
        errors = self.mean_errors(shown)
        lines.append(f"| **mean** ({len(self.rows)} trials) |" + " |" * (len(columns) - 1) + " "
                     + " | ".join(f"**{errors[m]:.4f}**" for m in shown) + " |")
        lines += ["", f"CRB against classical: {crb_reduction(errors):+.1f} % (positive: CRB is better)."]
        return "\n".join(lines)
