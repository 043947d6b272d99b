"""The paper's experimental campaign (Sec. VI) in simulation: dataset, Table I and figures.

Trials: every posture x every normal speed (paper: 0.08, 0.10, 0.12, 0.15, 0.18 m/s), plus the
tangential series on the first posture (paper: v_t = 0.03 .. 0.12 m/s at v_n = 0.12 m/s) along the
surface tangent t = normalise(n x e_z) of ``sim.generation`` (+y for the default wall). Each
trial is one ``scenarios.trial`` run with the jump-aware constraints off, so that the tool hits at
the requested speed, as in the paper. The simulation is deterministic: one trial per setting
stands for the paper's ten repeats.

Table I (``scenarios.campaign_table``, one table for every robot): for each trial and predictor,
the average prediction error (26) e = (1/n) sum_i |dq*_i - dq°_i| (n joints) of the predictor's
own jump at the pre-impact state against the simulated jump dq°, and the reduction
100 (1 - e_crb / e_classical) % of CRB against the classical prediction (the paper's 81.98 %); the
last row averages every trial.

An arm's figures (PNG, ``scenarios.campaign_figures``): per posture, the simulated jump of every joint against the normal speed (like the
paper's Fig. 8) and the absolute error |e_i| of every predictor of Table I per joint (Figs. 9-11),
each kind on one y scale for all postures; for the tangential series, the average error of
every predictor against v_t (Fig. 12).

Output directory: the dataset (``controller.measured.dataset``: ``dataset.json`` and one CSV pair per trial),
Table I's ``table1.json`` and ``table1.md`` (``scenarios.campaign_table.TABLE_FILES``, for every
robot) and the figures; every file written atomically.

One :class:`Campaign` runs every robot: it is given the robot's trials (:class:`CampaignTrials`,
parametrised by the robot's description: its named postures, or with held contacts its stances;
each trial one ``scenarios.trial.TrialRunner`` run, an arm's driven by its QP, a standing robot's
by the scripted arm), writes each trial to the dataset as it comes, then Table I (its files and
figures).

A floating base's campaign: its stances x hand speeds of ``sim.runner.run_impact_trial`` (also
:func:`run_stance_trials`, with the plant's gain and armature), no tangential series. For each trial and predictor (classical, gm,
crb, each fed its own impulse; ``momentum``: the feet-held momentum law fed the measured impulse)
the average error (26) over the joints; its Table I (``table1.json`` and ``table1.md``,
without figures) gives per stance and speed the measured contact speed, the
impulse, the CoM velocity jump, the foot slip and lift, whether the robot fell, and the errors.
"""

from __future__ import annotations

from contextlib import closing
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice  # noqa: E402
from impactqp.controller.model.postures import DEFAULT_WALL, Surface  # noqa: E402
from impactqp.controller.model.humanoid_stance import stance_posture  # noqa: E402
from impactqp.controller.measured.atomic import write_text_atomic  # noqa: E402
from impactqp.sim.generation import DEFAULT_SPEEDS, TANGENTIAL_SERIES_NORMAL_SPEED, tangential_direction  # noqa: E402
from impactqp.controller.measured.dataset import DatasetHeader  # noqa: E402
from impactqp.controller.measured.dataset_writer import DatasetWriter, check_room  # noqa: E402
from impactqp.controller.model.robot_description import RobotDescription  # noqa: E402
from impactqp.sim.plant import PlantParameters  # noqa: E402
from impactqp.sim.generation import dataset_bytes, dataset_header  # noqa: E402

from impactqp.sim.runner import TrialSpec  # noqa: E402
from impactqp.controller.model.robot import RobotModel  # noqa: E402
from impactqp.sim.generation import STANDING_WALL  # noqa: E402
from impactqp.sim.runner import SERVO_GAIN, run_impact_trial  # noqa: E402
from impactqp.sim.trial_result import TrialResult  # noqa: E402
from impactqp.sim.trial_sources import SCRIPTED  # noqa: E402

from .campaign_table import Table1  # noqa: E402
from .trial import TrialPool  # noqa: E402
from impactqp.controller.model.validation import (  # noqa: E402
    MAX_TRIALS,
    BadInputError,
    counted,
    distinct_names,
    simulated_speed,
    tangential_speed,
    trial_count,
)

PAPER_SPEEDS = DEFAULT_SPEEDS
PAPER_TANGENTIAL_SPEEDS = tuple(round(0.03 + 0.01 * i, 2) for i in range(10))
TANGENTIAL_NORMAL_SPEED = TANGENTIAL_SERIES_NORMAL_SPEED
STANCE_SPEEDS = (0.1, 0.2, 0.3, 0.4)
"""m/s: a floating base's commanded hand speeds."""


def named_postures(robot: RobotDescription) -> Mapping:
    """The postures a campaign of ``robot`` may run: a floating base's stances, a fixed base's
    named impact postures (its description's)."""
    return robot.stances if robot.floating else robot.postures


def check_postures(robot: RobotDescription, names) -> tuple[str, ...]:
    """``names`` (None: every named posture of ``robot``) as a tuple, each checked."""
    known = named_postures(robot)
    names = tuple(known) if names is None else tuple(names)
    distinct_names(names, "the postures")
    for name in names:
        if name not in known:
            raise BadInputError(f"unknown posture {name!r} for the {robot.name}; known: {', '.join(known)}")
    return names


def posture_of(choice: RobotChoice, name: str) -> np.ndarray:
    """The configuration of the named posture ``name`` of ``choice``'s robot: a stance's posture
    with held contacts (``controller.model.humanoid_stance``), else the named impact posture solved
    for the tool."""
    if choice.robot.held_contacts:
        return stance_posture(choice.shared_model, choice.robot.stances[name])
    return choice.posture(name).q


@dataclass(frozen=True)
class CampaignPlan:
    """Which trials the campaign runs (module docstring); ``postures`` None: every named posture
    of the robot (a floating base's: its stances)."""

    postures: tuple[str, ...] | None = None
    speeds: tuple[float, ...] = PAPER_SPEEDS
    tangential_speeds: tuple[float, ...] = PAPER_TANGENTIAL_SPEEDS
    tangential_normal_speed: float = TANGENTIAL_NORMAL_SPEED
    max_trials: int = MAX_TRIALS

    def __post_init__(self):
        if self.postures is not None and not self.postures:
            raise BadInputError("the campaign needs at least one posture")
        if not self.speeds:
            raise BadInputError("the campaign needs at least one speed")
        for v in self.speeds:
            simulated_speed(v, "every normal speed")
        for v in self.tangential_speeds:
            tangential_speed(v, "every tangential speed")

    def specs(self, surface: Surface, choice: RobotChoice = DEFAULT_CHOICE) -> list[TrialSpec]:
        """The trials, at ``choice``'s named postures (:func:`posture_of`); bad input for a
        posture the robot does not have, or for a tangential series of a robot with held contacts
        (its hand moves along the wall normal)."""
        postures = check_postures(choice.robot, self.postures)
        if self.tangential_speeds and choice.robot.held_contacts:
            raise BadInputError(f"the {choice.robot.name}'s campaign has no tangential series")
        trial_count(
            len(postures) * len(self.speeds) + len(self.tangential_speeds), self.max_trials, "the campaign",
            f"{counted(len(postures), 'posture')} x {counted(len(self.speeds), 'speed')}"
            f" + {len(self.tangential_speeds)} tangential",
        )
        specs = [
            TrialSpec(name, posture_of(choice, name), float(speed))
            for name in postures
            for speed in self.speeds
        ]
        tangent = tangential_direction(surface.normal)
        first = postures[0]
        specs += [
            TrialSpec(first, posture_of(choice, first), self.tangential_normal_speed, float(v_t) * tangent)
            for v_t in self.tangential_speeds
        ]
        return specs


@dataclass(frozen=True)
class CampaignTrials:
    """The campaign's trials of ``choice``'s robot and tool (module docstring): the plan's
    trials (``CampaignPlan.specs``) run by ``scenarios.trial`` (its ``TrialPool``) on ``surface``
    and ``plant`` (None: the default plant), each written to the dataset of the robot's wall
    (with held contacts ``sim.generation.STANDING_WALL``: each stance puts its wall before its
    hand), then Table I of the results."""

    choice: RobotChoice = DEFAULT_CHOICE
    surface: Surface = DEFAULT_WALL
    plant: PlantParameters | None = None

    @property
    def header(self) -> DatasetHeader:
        return dataset_header(STANDING_WALL if self.choice.robot.held_contacts else self.surface, self.choice)

    def tasks(self, plan: CampaignPlan) -> list[TrialSpec]:
        return plan.specs(self.surface, self.choice)

    def results(self, tasks: list[TrialSpec], jobs: int) -> Iterator:
        with TrialPool(self.surface, self.plant, jobs, self.choice) as pool:
            yield from pool.map(tasks)

    def table(self, results: list[TrialResult]) -> Table1:
        """Table I of the results in the robot's layout (``scenarios.campaign_table``)."""
        return Table1.of(self.choice.robot, results)


class Campaign:
    """Runs a :class:`CampaignPlan` with the trials ``trials`` of one robot
    (:class:`CampaignTrials`) on ``jobs`` worker processes and writes its outputs."""

    def __init__(self, plan: CampaignPlan, trials: CampaignTrials, *, jobs: int = 1, progress: bool = False):
        self.plan = plan
        self.trials = trials
        self.jobs = jobs
        self.progress = progress

    def run(self, out: str | Path) -> Table1:
        """Run every trial, adding each to the dataset in ``out`` as it comes, then write Table I's
        files and figures there; an existing dataset of another header, or a folder that cannot be
        written or lacks the room for the trials' estimated size (``check_room``), is refused first."""
        out = Path(out)
        tasks = self.trials.tasks(self.plan)
        check_room(out, dataset_bytes(tasks, self.trials.choice.robot), f"the {counted(len(tasks), 'trial')}")
        writer = DatasetWriter(out, self.trials.header, expected_trials=len(tasks))
        results = []
        with closing(self.trials.results(tasks, self.jobs)) as running:  # its pool ends with the loop
            for result in tqdm(running, total=len(tasks), desc="campaign", unit="trial", disable=None if self.progress else True):
                writer.add_trial(*result.dataset_trial())
                results.append(result)
        table = self.trials.table(results)
        for name, text in table.files().items():
            write_text_atomic(out / name, text)
        choice = self.trials.choice
        table.write_figures(out, f"{choice.robot.name} with {choice.tool.name if choice.tool else 'its hand'}")
        return table


# ---------------------------------------------------------------------------- a floating base's campaign


def run_stance_trials(
    robot: RobotModel,
    stances: Iterable[str] | None = None,
    speeds: Iterable[float] = STANCE_SPEEDS,
    gain: float = SERVO_GAIN,
    armature=None,
    source=SCRIPTED,
) -> list[TrialResult]:
    """One trial per stance (None: every stance of the robot's description) and commanded hand
    speed (m/s); ``gain`` is the servo bandwidth (rad/s), ``armature`` the plant's rotor inertia
    (kg m^2): None for the G1's actuators (``controller.model.g1_actuators``), one number for every
    joint (0: link-only) or one per joint; ``source`` the command source
    (``sim.trial_sources``: ``SCRIPTED`` or ``QpCommand``)."""
    all_stances = robot.description.stances
    return [
        run_impact_trial(robot, all_stances[name], speed, gain=gain, armature=armature, source=source)
        for name in (all_stances if stances is None else stances)
        for speed in speeds
    ]
