"""Highest feasible contact speed of a posture: closed form, QP-limited, and simulated.

Three answers to "how fast may the tool hit the surface at this posture?" (docs/max-speed.md,
criteria (a) pre-impact velocity, (b) post-impact velocity, (c) impulsive torque):

predicted_max_speed
    ``controller.model.max_speed.closed_form_max_speed`` at the contact posture q_impact (the joint
    posture at the impact of the QP-limited run: the named posture moved by its run-up) for the
    classical, gm and crb models (dq- = J6+ [-v n; 0], dq+ = dq- + the model's jump, torque from
    the model's own impulse over delta_t), with what binds (criterion and joint); ``robust`` is
    the smallest of the three (its constraints satisfy all models).
qp_limited_speed
    The contact speed the QP controller reaches by itself when asked for 2 m/s with the
    jump-aware constraints of ``jump_model`` on, starting at rest 5 cm from the surface (farther
    when the predicted maximum needs a longer run-up, ``qp_start_distance``); with the velocity
    and impulsive-torque ratios the simulation observed in that run.
simulated_max_speed
    The highest reference speed whose simulated impact stays feasible with the jump-aware
    constraints off (observed criteria of ``scenarios.trial``: max |dq|/dq_max over the 50 ms
    after the impact and |J^T iota_sim| / delta_t_sim / tau_max). A parallel bisection: each
    round simulates ``jobs`` reference speeds evenly spaced inside the bracket [lo, hi] (lo
    feasible, hi violated) and keeps the highest feasible speed below the lowest violated one,
    until hi - lo <= tolerance. The first bracket is [v_lo, v_a] with v_lo = 0.02 m/s and v_a the
    speed at which the approach itself brings a joint to its velocity limit (criterion (a), the
    same for every model; taken 0.1 % below); when v_a is still feasible the answer is v_a, when v_lo is violated
    it is 0. Feasibility is assumed monotone in the speed (checked by the tests).

A floating base standing on held contacts (the G1, docs/floating-base.md) is searched per stance
of its description (:func:`search_stance`): the closed form at the stance (the smallest of the
joint-velocity, foot-slip, foot-lift and capture bounds, and which one binds) and the same
bisection (:class:`SpeedBisection`, one trial a round) on the commanded hand speed of
``sim.runner.run_impact_trial`` between :data:`STANCE_LOWEST_SPEED` (feasible) and
:data:`STANCE_HIGHEST_SPEED`, a trial feasible when none of its measured failures occurred (no
joint beyond its velocity limit, no foot slip or lift onset in the impact window, the post-impact
CoM velocity capturable, no fall): the highest feasible commanded speed, its measured contact
speed, and what failed first at the lowest infeasible one (no QP-limited run). Its check against
simulation and its tables and figure: ``scenarios.stance_check``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from tqdm import tqdm

from impactqp.controller.model.max_speed import (
    DEFAULT_IMPACT_DURATION,
    MaxSpeed,
    Setting,
    approach_direction,
    closed_form_max_speed,
)
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.validation import MAX_CONTACT_SPEED, BadInputError
from impactqp.sim.runner import NORMAL, SERVO_GAIN, run_impact_trial
from impactqp.sim.trial_result import TrialResult
from impactqp.sim.trial_sources import SCRIPTED
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.postures import ImpactPosture, Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import impact_duration as check_impact_duration
from impactqp.controller.model.validation import restitution as restitution_coefficient
from impactqp.constraints import jump_model_names
from impactqp.sim.plant import PlantParameters

from impactqp.sim.runner import TrialSpec

from .stance_evaluation import StanceEvaluation, StanceMaxSpeed
from .trial import TrialPool
from impactqp.controller.model.validation import number_in_range

PREDICTED_MODELS = ("classical", "gm", "crb")
QP_REQUEST_SPEED = 2.0
QP_START_DISTANCE = 0.05
# The QP-limited run starts at rest far enough to reach the predicted maximum at the contact
# point's acceleration a under the joint acceleration and jerk limits (docs/max-speed.md, "In
# simulation"), with a run-up 50 % longer than v^2 / (2 a).
RUN_UP_ACCELERATION = 4.0
RUN_UP_MARGIN = 1.5


def qp_start_distance(predicted_speed: float) -> float:
    """Start distance of the QP-limited run: QP_START_DISTANCE, or the run-up the predicted
    maximum speed needs when that is longer."""
    return max(QP_START_DISTANCE, RUN_UP_MARGIN * predicted_speed**2 / (2.0 * RUN_UP_ACCELERATION))
LOWEST_SPEED = 0.02
DEFAULT_TOLERANCE = 0.005
MIN_TOLERANCE, MAX_TOLERANCE = 1e-4, 0.5
"""m/s: below 0.1 mm/s the bisection resolves nothing a simulated impact can tell apart, and the
number of simulated impacts grows as log(1 / tolerance)."""
# the top of the first bracket, just below v_a: a start state exactly at a joint velocity limit
# would read as outside it after rounding
APPROACH_LIMIT_FRACTION = 0.999


@dataclass(frozen=True)
class Evaluation:
    """One simulated impact of the bisection (reference speed, what happened)."""

    reference_speed: float
    contact_speed: float
    max_velocity_ratio: float
    max_torque_ratio: float
    violated: bool

    @classmethod
    def of(cls, result: TrialResult) -> Evaluation:
        return cls(
            result.normal_speed, result.contact_speed, result.max_velocity_ratio,
            result.max_torque_ratio, result.violated,
        )

    def to_json(self) -> dict:
        return {
            "reference_speed": self.reference_speed,
            "contact_speed": self.contact_speed,
            "max_velocity_ratio": self.max_velocity_ratio,
            "max_torque_ratio": self.max_torque_ratio,
            "violated": self.violated,
        }


@dataclass(frozen=True)
class MaxSpeedReport:
    """Everything ``impactqp max-speed --json`` prints."""

    posture: str
    q_impact: np.ndarray
    normal: np.ndarray
    jump_model: str
    predicted: dict[str, MaxSpeed]
    qp_limited: TrialResult
    simulated_max_speed: float
    evaluations: list[Evaluation]

    def to_json(self) -> dict:
        return {
            "posture": self.posture,
            "q_impact": self.q_impact.tolist(),
            "normal": self.normal.tolist(),
            "jump_model": self.jump_model,
            "predicted_max_speed": {name: m.speed for name, m in self.predicted.items()},
            "binding": {name: {"criterion": m.criterion, "joint": m.joint} for name, m in self.predicted.items()},
            "qp_limited_speed": self.qp_limited.contact_speed,
            "qp_max_velocity_ratio": self.qp_limited.max_velocity_ratio,
            "qp_max_torque_ratio": self.qp_limited.max_torque_ratio,
            "simulated_max_speed": self.simulated_max_speed,
            "evaluations": [e.to_json() for e in self.evaluations],
        }


def binding_text(binding: dict) -> str:
    """What binds a predictor's speed in a report's ``binding``: ``criterion, joint N`` or
    ``criterion (where)``."""
    return binding["criterion"] + (f", joint {binding['joint']}" if "joint" in binding else f" ({binding['where']})")


def predicted_max_speeds(
    robot: PandaModel, q: np.ndarray, normal: np.ndarray, restitution: float, impact_duration: float
) -> dict[str, MaxSpeed]:
    """The closed-form maximum speed of classical, gm and crb at q (controller.model.max_speed), and
    of ``robust``, the constraints' setting that satisfies all three: the smallest of them."""
    terms = robot.terms(q)
    maxima = {
        name: closed_form_max_speed(robot, terms, normal, Setting(name, restitution, impact_duration=impact_duration))
        for name in PREDICTED_MODELS
    }
    maxima["robust"] = min(maxima.values(), key=lambda m: m.speed)
    return maxima


def approach_velocity_limit(robot: PandaModel, q: np.ndarray, normal: np.ndarray) -> float:
    """v_a = 1 / max_i |d_i| / dq_max_i: the approach speed at which dq- = v d reaches a joint
    velocity limit (criterion (a))."""
    d = approach_direction(robot, robot.terms(q), normal)
    return float(1.0 / np.max(np.abs(d) / robot.dq_max))


def bisection_tolerance(value, what: str, smallest: float = MIN_TOLERANCE) -> float:
    """A bisection tolerance (m/s) in [smallest, MAX_TOLERANCE]: ``max-speed --tolerance``'s and a
    sweep's ``simulate.tolerance``."""
    return number_in_range(value, smallest, MAX_TOLERANCE, what, "m/s")


class SpeedBisection:
    """The bracket [lo, hi] of the parallel bisection of the module docstring (``smallest``: the
    least tolerance accepted, m/s)."""

    def __init__(self, lo: float, hi: float, tolerance: float, smallest: float = MIN_TOLERANCE):
        tolerance = bisection_tolerance(tolerance, "the bisection tolerance", smallest)
        self.lo, self.hi, self.tolerance = lo, hi, tolerance
        self.evaluations: list = []

    @property
    def done(self) -> bool:
        return self.hi - self.lo <= self.tolerance

    def next_speeds(self, count: int) -> list[float]:
        """``count`` speeds evenly spaced strictly inside (lo, hi)."""
        return [float(v) for v in np.linspace(self.lo, self.hi, count + 2)[1:-1]]

    def update(self, evaluations: list) -> None:
        """Keep the highest feasible speed below the lowest violated one."""
        self.evaluations += evaluations
        for e in sorted(evaluations, key=lambda e: e.reference_speed):
            if self.lo < e.reference_speed < self.hi:
                if e.violated:
                    self.hi = e.reference_speed
                    break
                self.lo = e.reference_speed

    def search(self, evaluate: Callable[[list[float]], list], jobs: int = 1, ends: list | None = None) -> float:
        """The highest feasible speed of the bracket: ``evaluate(speeds)`` simulates one trial per
        speed (the plant's trial: the arm's ``TrialPool``, the G1's ``Plant.trial``) and returns one
        evaluation each (``reference_speed``, ``violated``); ``ends``: the evaluations at lo and hi
        when already made. 0 when lo is violated, hi when hi holds, else ``jobs`` speeds a round
        until the bracket is within the tolerance; every evaluation is kept in ``evaluations``."""
        ends = evaluate([self.lo, self.hi]) if ends is None else ends
        self.evaluations += ends
        if ends[0].violated:
            return 0.0
        if not ends[1].violated:
            return self.hi
        while not self.done:
            self.update(evaluate(self.next_speeds(jobs)))
        return self.lo


@dataclass(frozen=True)
class QpSetting:
    """The impact setting of the QP in a search's trials: its jump model (a key of
    ``constraints.impact_model.JUMP_MODEL_CHOICES``), the restitution c_r and the impact duration
    delta_t (s) of its rows; checked when made (bad input)."""

    jump_model: str = "crb"
    restitution: float = 0.0
    impact_duration: float = DEFAULT_IMPACT_DURATION

    def __post_init__(self):
        jump_model_names(self.jump_model)
        object.__setattr__(self, "restitution", restitution_coefficient(self.restitution))
        object.__setattr__(self, "impact_duration", check_impact_duration(self.impact_duration))


class MaxSpeedSearch:
    """The three maximum speeds of one posture on one surface and plant (module docstring), the
    QP of the trials set by ``setting``."""

    def __init__(
        self,
        posture: ImpactPosture,
        surface: Surface,
        plant: PlantParameters | None = None,
        *,
        setting: QpSetting = QpSetting(),
        tolerance: float = DEFAULT_TOLERANCE,
        jobs: int = 1,
        progress: bool = False,
        choice: RobotChoice = DEFAULT_CHOICE,
    ):
        self.posture = posture
        self.surface = surface
        self.plant = plant
        self.jump_model = setting.jump_model
        self.restitution = setting.restitution
        self.impact_duration = setting.impact_duration
        self.tolerance = tolerance
        self.jobs = jobs
        self.progress = progress
        self.choice = choice
        self.robot = choice.shared_model

    def spec(self, speed: float, **changes) -> TrialSpec:
        return TrialSpec(
            self.posture.name, self.posture.q, speed, restitution=self.restitution,
            impact_duration=self.impact_duration, **changes,
        )

    def run(self) -> MaxSpeedReport:
        q, normal = self.posture.q, self.surface.normal
        # at the named posture: only to size the QP run's run-up
        predicted = predicted_max_speeds(self.robot, q, normal, self.restitution, self.impact_duration)
        highest = min(APPROACH_LIMIT_FRACTION * approach_velocity_limit(self.robot, q, normal), MAX_CONTACT_SPEED)
        if not highest > LOWEST_SPEED:
            raise BadInputError(
                f"at {self.posture.name} the approach reaches a joint velocity limit at {highest:.3g} m/s, below the "
                f"search's lowest speed {LOWEST_SPEED} m/s"
            )
        bisection = SpeedBisection(LOWEST_SPEED, highest, self.tolerance)
        target = min(predicted[name].speed for name in jump_model_names(self.jump_model))
        qp_spec = self.spec(
            QP_REQUEST_SPEED, jump_model=self.jump_model, start_at_rest=True,
            start_distance=qp_start_distance(target),
        )
        # upper bound of the number of trials, for the progress bar
        width = bisection.hi - bisection.lo
        rounds = int(np.ceil(np.log(width / self.tolerance) / np.log(self.jobs + 1))) + 1
        with TrialPool(self.surface, self.plant, self.jobs, self.choice) as pool, tqdm(
            total=2 + rounds * self.jobs, desc=f"max-speed {self.posture.name}", unit="trial",
            disable=None if self.progress else True,
        ) as bar:
            first = [qp_spec, self.spec(bisection.lo), self.spec(bisection.hi)]
            qp_limited, *ends = list(pool.map(first))
            bar.update(len(first))

            def evaluate(speeds: list[float]) -> list[Evaluation]:
                results = [Evaluation.of(r) for r in pool.map([self.spec(v) for v in speeds])]
                bar.update(len(results))
                return results

            simulated = bisection.search(evaluate, self.jobs, [Evaluation.of(r) for r in ends])
            bar.total = bar.n
            bar.refresh()
        q_impact = qp_limited.impact.q_pre.copy()
        predicted = predicted_max_speeds(self.robot, q_impact, normal, self.restitution, self.impact_duration)
        return MaxSpeedReport(
            posture=self.posture.name,
            q_impact=q_impact,
            normal=normal.copy(),
            jump_model=self.jump_model,
            predicted=predicted,
            qp_limited=qp_limited,
            simulated_max_speed=float(simulated),
            evaluations=sorted(bisection.evaluations, key=lambda e: e.reference_speed),
        )


# ---------------------------------------------------------------------------- a floating base's stances
STANCE_LOWEST_SPEED = 0.05  # m/s commanded
STANCE_HIGHEST_SPEED = 3.0  # m/s commanded: above what the torque-limited hand reaches in the 2 cm to the wall
STANCE_TOLERANCE = 0.02  # m/s
STANCE_MIN_TOLERANCE = 1e-3  # m/s: the least bisection tolerance of a stance


@dataclass(frozen=True)
class StancePlant:
    """A floating base's simulated plant: servo bandwidth (rad/s) and rotor inertia (kg m^2): None for the G1's
    actuators, one number for every joint (0: link-only) or one per joint."""

    gain: float = SERVO_GAIN
    armature: float | tuple | None = None

    def trial(self, robot: RobotModel, stance: str, q: np.ndarray, speed: float, source=SCRIPTED) -> TrialResult:
        """One trial on this plant: ``stance`` from the configuration q at the commanded hand
        ``speed``, driven by ``source``."""
        return run_impact_trial(
            robot, robot.description.stances[stance], speed, gain=self.gain, armature=self.armature, q0=q, source=source
        )


def predicted_speeds(robot: RobotModel, q: np.ndarray, setting: Setting, methods) -> dict[str, MaxSpeed]:
    """The closed form of each predictor in ``methods`` (same restitution, friction and duration)."""
    terms = robot.terms(q)
    return {
        m: closed_form_max_speed(robot, terms, NORMAL, Setting(m, setting.restitution, setting.friction, setting.impact_duration))
        for m in methods
    }


@dataclass(frozen=True)
class SpeedChecks:
    """The trials a stance search asks for besides its bisection: one at each of ``factors`` times
    ``reference`` (m/s: a closed form the caller took at the stance, as the frictional one of
    ``friction_max_speed.frictional_max_speed``; None: the stance's frictionless crb closed form)."""

    factors: tuple = ()
    reference: float | None = None


def search_stance(
    robot: RobotModel, stance: str, setting: Setting = Setting(), plant: StancePlant = StancePlant(),
    tolerance: float = STANCE_TOLERANCE, methods=("classical", "gm", "crb"), source=SCRIPTED,
    checks: SpeedChecks = SpeedChecks(),
) -> StanceMaxSpeed:
    """The closed-form speeds of ``methods`` and the simulated bisection of one stance, its trials
    driven by ``source`` (``sim.trial_sources``: ``SCRIPTED`` or ``QpCommand``), and the trials of
    ``checks`` (:class:`SpeedChecks`; ``methods`` must hold crb when it has no reference)."""
    stances = robot.description.stances
    if stance not in stances:
        raise BadInputError(f"unknown stance {stance!r}; known: {', '.join(stances)}")
    q = stance_posture(robot, stances[stance])
    run = partial(plant.trial, robot, stance, q, source=source)
    bisection = SpeedBisection(STANCE_LOWEST_SPEED, STANCE_HIGHEST_SPEED, tolerance, STANCE_MIN_TOLERANCE)
    best = bisection.search(lambda speeds: [StanceEvaluation.of_speed(run, speed) for speed in speeds])
    evaluations = bisection.evaluations
    feasible = [e for e in evaluations if not e.violated and e.reference_speed <= best]
    failed = [e for e in evaluations if e.violated]
    contact = max(feasible, key=lambda e: e.reference_speed).contact_speed if feasible else 0.0
    first = min(failed, key=lambda e: e.reference_speed).first_failure if failed else ""
    predicted = predicted_speeds(robot, q, setting, methods)
    reference = predicted["crb"].speed if checks.reference is None else checks.reference
    checked = {factor: StanceEvaluation.of_speed(run, factor * reference) for factor in checks.factors}
    return StanceMaxSpeed(stance, q, predicted, best, contact, first, evaluations, checked)
