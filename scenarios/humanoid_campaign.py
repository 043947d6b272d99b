"""The humanoid campaign: stances x hand speeds of ``sim.humanoid_trial``, and its table.

For each trial and predictor (classical, gm, crb, each fed its own impulse; ``momentum``: the
feet-held momentum law fed the measured impulse) the average error (26) over the joints; the
table gives per stance and speed the measured contact speed, the impulse, the CoM velocity jump,
the foot slip and lift, whether the robot fell, and the errors; its last row averages the errors
over every trial, with the reduction 100 (1 - e_crb / e_classical) % of CRB against classical
(negative when CRB is worse).

:class:`FloatingBaseTrials` is the trial runner of a floating-base robot that
``scenarios.campaign.Campaign`` is given (the plan's postures are the description's stances, no
tangential series); its Table I (:class:`FloatingBaseTable`) is ``table1.json`` and the Markdown
table ``table1.md``, without figures.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import DatasetHeader, TrialEntry
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel
from impactqp.controller.model.robot_description import RobotDescription
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.generation import STANDING_WALL, dataset_header, dataset_log, trial_entry
from impactqp.sim.humanoid_trial import SCRIPTED, SERVO_GAIN, ImpactTrial, run_impact_trial
from impactqp.sim.process_pool import map_in_processes

from .campaign import CampaignPlan, check_postures

DEFAULT_SPEEDS = (0.1, 0.2, 0.3, 0.4)
PREDICTORS = (*METHODS, "momentum")


def run_campaign(
    robot: FloatingBaseModel,
    stances: Iterable[str] | None = None,
    speeds: Iterable[float] = DEFAULT_SPEEDS,
    gain: float = SERVO_GAIN,
    armature=None,
    source=SCRIPTED,
) -> list[ImpactTrial]:
    """One trial per stance (None: every stance of the robot's description) and commanded hand
    speed (m/s); ``gain`` is the servo bandwidth (rad/s), ``armature`` the plant's rotor inertia
    (kg m^2): None for the G1's actuators (``controller.model.g1_actuators``), one number for every
    joint (0: link-only) or one per joint; ``source`` the command source
    (``sim.humanoid_trial.SCRIPTED`` or ``sim.humanoid_qp_source.QpCommand``)."""
    all_stances = robot.description.stances
    return [
        run_impact_trial(robot, all_stances[name], speed, gain=gain, armature=armature, source=source)
        for name in (all_stances if stances is None else stances)
        for speed in speeds
    ]


def _campaign_trial(task: tuple[RobotDescription, str, float]) -> ImpactTrial:
    """One campaign trial (robot description, stance, speed) in a worker process."""
    robot, stance, speed = task
    return run_campaign(FloatingBaseModel(robot), (stance,), (speed,))[0]


def trial_json(robot: str, trial: ImpactTrial) -> dict:
    """A trial of the floating-base robot named ``robot`` as JSON (sim.humanoid_trial.ImpactTrial)."""
    return {
        "robot": robot, "posture": trial.stance, "reference_speed": trial.speed, "contact_speed": trial.contact_speed,
        "impulse": trial.impulse.tolist(), "floor_impulse": trial.floor_impulse.tolist(),
        "impact_duration": trial.duration, "dq_jump": trial.measured_jump.tolist(),
        "com_jump": trial.measured_com_jump.tolist(),
        "predicted": {m: dv.tolist() for m, dv in trial.predicted_jump.items()},
        "predicted_com_jump": {m: c.tolist() for m, c in trial.predicted_com_jump.items()},
        "errors": trial.errors, "foot_slip": trial.foot_slip, "foot_lift": trial.foot_lift, "fell": trial.fell,
        "max_velocity_ratio": trial.max_velocity_ratio, "first_failure": trial.first_failure,
        "violated": not trial.feasible,
    }


@dataclass(frozen=True)
class FloatingBaseTrials:
    """The campaign's trials of the floating-base robot ``robot`` (``scenarios.campaign``'s
    ``CampaignTrials``): the scripted hand at each stance and speed, on the default plant, its
    trials written as a dataset of the wall (``sim.generation``)."""

    robot: RobotDescription

    @property
    def header(self) -> DatasetHeader:
        return dataset_header(STANDING_WALL, RobotChoice(self.robot))

    def tasks(self, plan: CampaignPlan) -> list[tuple[RobotDescription, str, float]]:
        """(robot, stance, speed) per trial: the plan's stances (None: every stance) x speeds; bad
        input for a stance the robot does not have or a tangential series (none here)."""
        if plan.tangential_speeds:
            raise BadInputError(f"the {self.robot.name}'s campaign has no tangential series")
        stances = check_postures(self.robot, plan.postures)
        return [(self.robot, stance, float(speed)) for stance in stances for speed in plan.speeds]

    def results(self, tasks: list, jobs: int) -> Iterator[ImpactTrial]:
        yield from map_in_processes(_campaign_trial, tasks, jobs)

    def dataset_trial(self, trial: ImpactTrial) -> tuple[TrialEntry, TrialLog]:
        return trial_entry(trial), dataset_log(trial)

    def table(self, trials: list[ImpactTrial]) -> FloatingBaseTable:
        return FloatingBaseTable(self.robot.name, trials)


@dataclass(frozen=True)
class FloatingBaseTable:
    """Table I of a floating-base robot's campaign (module docstring)."""

    robot: str
    trials: list[ImpactTrial]

    def to_json(self) -> dict:
        """Table I's JSON: per trial the trial's JSON (``trial_json``) but its predictions, with the
        arm's row keys; the errors (26) averaged over the trials and CRB's reduction."""
        errors = {m: e for m, e in mean_errors(self.trials).items() if m in METHODS}
        rows = [
            {**{k: v for k, v in trial_json(self.robot, t).items() if k not in ("predicted", "predicted_com_jump", "robot")},
             "trial": i, "normal_speed": t.speed, "tangential_speed": 0.0, "average_error": t.errors,
             "crb_reduction_percent": crb_reduction(t.errors), "measured_jump": t.measured_jump.tolist()}
            for i, t in enumerate(self.trials)
        ]
        return {"robot": self.robot, "methods": list(METHODS), "rows": rows, "mean_average_error": errors,
                "mean_crb_reduction_percent": crb_reduction(errors)}

    def text(self) -> str:
        return campaign_table(self.trials)

    def files(self) -> dict[str, str]:
        """The table's files by name: its JSON and the Markdown table."""
        return {"table1.json": json.dumps(self.to_json(), indent=2, allow_nan=False), "table1.md": self.text() + "\n"}

    def write_figures(self, out: Path) -> list[Path]:
        """No figures: the table is the campaign's summary."""
        return []


def mean_errors(trials: list[ImpactTrial]) -> dict[str, float]:
    """Eq. (26) averaged over the trials, per predictor."""
    return {m: float(np.mean([t.errors[m] for t in trials])) for m in PREDICTORS}


def crb_reduction(errors: dict[str, float]) -> float:
    """100 (1 - e_crb / e_classical) %: how much CRB cuts the classical error (negative: worse)."""
    return 100.0 * (1.0 - errors["crb"] / errors["classical"])


def campaign_table(trials: list[ImpactTrial]) -> str:
    """The campaign as a Markdown table (module docstring)."""
    head = ("| stance | v cmd (m/s) | v contact (m/s) | impulse n (N s) | CoM jump x (m/s) | slip (mm) | "
            "lift (mm) | fell | " + " | ".join(f"e {m}" for m in PREDICTORS) + " |")
    lines = [head, "|" + "---|" * (8 + len(PREDICTORS))]
    for t in trials:
        lines.append(
            f"| {t.stance} | {t.speed:.2f} | {t.contact_speed:.3f} | {-t.impulse[0]:.3f} | "
            f"{t.measured_com_jump[0]:.4f} | {1e3 * t.foot_slip:.2f} | {1e3 * t.foot_lift:.2f} | "
            f"{'yes' if t.fell else 'no'} | " + " | ".join(f"{t.errors[m]:.4f}" for m in PREDICTORS) + " |"
        )
    errors = mean_errors(trials)
    lines.append(
        f"| **mean** ({len(trials)} trials) | | | | | | | | " + " | ".join(f"**{errors[m]:.4f}**" for m in PREDICTORS)
        + " |"
    )
    lines.append("")
    lines.append(f"CRB against classical: {crb_reduction(errors):+.1f} % (positive: CRB is better).")
    return "\n".join(lines)
