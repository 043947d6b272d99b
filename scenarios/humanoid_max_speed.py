"""Highest feasible contact speed of each G1 stance: closed form and simulated bisection, and
the check of one against the other (docs/floating-base.md; results: docs/results.md).

closed form
    ``controller.model.max_speed.closed_form_max_speed`` at the stance: the smallest of
    the joint-velocity, foot-slip, foot-lift and capture bounds, and which one binds.
simulated bisection
    ``sim.humanoid_trial.run_impact_trial`` at commanded hand speeds; a trial is feasible when
    none of the trial's measured failures occurred (no joint beyond its velocity limit, no
    foot slip or lift onset in the impact window, the post-impact CoM velocity capturable, no
    fall). The arm's bisection (``scenarios.max_speed_search.SpeedBisection``, one trial a
    round, ``Plant.trial`` injected) on the commanded speed between :data:`LOWEST_SPEED`
    (feasible) and :data:`HIGHEST_SPEED` until the bracket is narrower than the tolerance; the answer is the
    highest feasible commanded speed, its measured contact speed, and what failed first at the
    lowest infeasible one. Feasibility is assumed monotone in the speed.
check
    Trials at contact speeds :data:`BELOW` x the closed-form speed must neither fall nor slip
    (a slip onset or a foot frame moved beyond 5 mm); at :data:`ABOVE` x (20 % and more above
    it) the binding criterion should be the failure seen first in the majority of trials
    (:data:`CRITERION_OF`: each measured failure is the closed form's criterion of the same
    name; a fall is none of them). A contact speed is reached by a secant search on the
    commanded speed (the servo lags the command).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.robot import RobotModel  # noqa: E402
from impactqp.controller.model.humanoid_stance import stance_posture  # noqa: E402
from impactqp.controller.model.max_speed import (  # noqa: E402
    HELD_CONTACT_CRITERIA,
    MaxSpeed,
    Setting,
    closed_form_max_speed,
)
from impactqp.controller.model.validation import BadInputError  # noqa: E402
from impactqp.scenarios.max_speed_search import SpeedBisection  # noqa: E402
from impactqp.sim.humanoid_trial import NORMAL, SCRIPTED, SERVO_GAIN, ImpactTrial, run_impact_trial  # noqa: E402

LOWEST_SPEED = 0.05  # m/s commanded
HIGHEST_SPEED = 3.0  # m/s commanded: above what the torque-limited hand reaches in the 2 cm to the wall
DEFAULT_TOLERANCE = 0.02  # m/s
MIN_TOLERANCE = 1e-3  # m/s: the least bisection tolerance of a stance
BELOW = (0.5, 0.8, 0.95)
ABOVE = (1.2, 1.3, 1.4)
SECANT_STEPS = 6
# a failure seen in simulation and the closed-form criterion it measures (a fall measures none)
CRITERION_OF = {criterion: criterion for criterion in HELD_CONTACT_CRITERIA}


@dataclass(frozen=True)
class Plant:
    """The simulated plant: servo bandwidth (rad/s) and rotor inertia (kg m^2): None for the G1's
    actuators, one number for every joint (0: link-only) or one per joint."""

    gain: float = SERVO_GAIN
    armature: float | tuple | None = None

    def trial(self, robot: RobotModel, stance: str, q: np.ndarray, speed: float, source=SCRIPTED) -> ImpactTrial:
        """One trial on this plant: ``stance`` from the configuration q at the commanded hand
        ``speed``, driven by ``source``."""
        return run_impact_trial(
            robot, robot.description.stances[stance], speed, gain=self.gain, armature=self.armature, q0=q, source=source
        )


@dataclass(frozen=True)
class StanceEvaluation:
    """One simulated trial of the search: commanded and contact speed (m/s), what failed."""

    reference_speed: float
    contact_speed: float
    max_velocity_ratio: float
    foot_slip: float
    foot_lift: float
    fell: bool
    first_failure: str

    @classmethod
    def of(cls, trial: ImpactTrial) -> StanceEvaluation:
        return cls(trial.speed, trial.contact_speed, trial.max_velocity_ratio, trial.foot_slip, trial.foot_lift,
                   trial.fell, trial.first_failure)

    @property
    def violated(self) -> bool:
        return bool(self.first_failure)

    def to_json(self) -> dict:
        return {
            "reference_speed": self.reference_speed, "contact_speed": self.contact_speed,
            "max_velocity_ratio": self.max_velocity_ratio, "foot_slip": self.foot_slip,
            "foot_lift": self.foot_lift, "fell": self.fell, "first_failure": self.first_failure,
            "violated": self.violated,
        }


@dataclass(frozen=True)
class StanceMaxSpeed:
    """Closed-form and simulated highest feasible speed of one stance."""

    stance: str
    q: np.ndarray
    predicted: dict  # method -> MaxSpeed
    simulated_reference: float  # highest feasible commanded speed (m/s)
    simulated_contact: float  # its measured contact speed (m/s)
    failed_first: str  # what failed first at the lowest infeasible commanded speed ("" if none)
    evaluations: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {
            "posture": self.stance,
            "q_impact": self.q.tolist(),
            "normal": NORMAL.tolist(),
            "predicted_max_speed": {m: p.to_json()["speed"] for m, p in self.predicted.items()},
            "binding": {m: {"criterion": p.criterion, "where": p.where} for m, p in self.predicted.items()},
            "bounds": {m: p.to_json()["bounds"] for m, p in self.predicted.items()},
            "simulated_max_speed": self.simulated_reference,
            "simulated_contact_speed": self.simulated_contact,
            "simulated_failed_first": self.failed_first,
            "evaluations": [e.to_json() for e in sorted(self.evaluations, key=lambda e: e.reference_speed)],
        }


def predicted_speeds(robot: RobotModel, q: np.ndarray, setting: Setting, methods) -> dict[str, MaxSpeed]:
    """The closed form of each predictor in ``methods`` (same restitution, friction and duration)."""
    terms = robot.terms(q)
    return {
        m: closed_form_max_speed(robot, terms, NORMAL, Setting(m, setting.restitution, setting.friction, setting.impact_duration))
        for m in methods
    }


def search_stance(
    robot: RobotModel, stance: str, setting: Setting = Setting(), plant: Plant = Plant(),
    tolerance: float = DEFAULT_TOLERANCE, methods=("classical", "gm", "crb"), source=SCRIPTED,
) -> StanceMaxSpeed:
    """The closed-form speeds of ``methods`` and the simulated bisection of one stance, its trials
    driven by ``source`` (``sim.humanoid_trial.SCRIPTED`` or ``sim.humanoid_qp_source.QpCommand``)."""
    stances = robot.description.stances
    if stance not in stances:
        raise BadInputError(f"unknown stance {stance!r}; known: {', '.join(stances)}")
    q = stance_posture(robot, stances[stance])
    run = partial(plant.trial, robot, stance, q, source=source)
    bisection = SpeedBisection(LOWEST_SPEED, HIGHEST_SPEED, tolerance, MIN_TOLERANCE)
    best = bisection.search(lambda speeds: [StanceEvaluation.of(run(speed)) for speed in speeds])
    evaluations = bisection.evaluations
    feasible = [e for e in evaluations if not e.violated and e.reference_speed <= best]
    failed = [e for e in evaluations if e.violated]
    contact = max(feasible, key=lambda e: e.reference_speed).contact_speed if feasible else 0.0
    first = min(failed, key=lambda e: e.reference_speed).first_failure if failed else ""
    return StanceMaxSpeed(stance, q, predicted_speeds(robot, q, setting, methods), best, contact, first, evaluations)


def trial_at_contact_speed(
    robot, stance: str, q: np.ndarray, target: float, plant: Plant, source=SCRIPTED
) -> ImpactTrial:
    """A trial whose measured contact speed is ``target`` within 2 % (secant on the commanded
    speed within [LOWEST_SPEED, 2 HIGHEST_SPEED], at most SECANT_STEPS trials; the closest one
    otherwise: with torque-limited joints a contact speed may be out of reach). A source that
    tracks the speed itself (``source.tracks_speed``: the whole-body QP) is asked ``target`` once."""
    run = partial(plant.trial, robot, stance, q, source=source)
    points = [(target, run(target))]
    if source.tracks_speed:
        return points[0][1]
    speed = 1.4 * target  # the hand reaches about 0.7 of the commanded speed
    for _ in range(SECANT_STEPS):
        points.append((speed, run(speed)))
        (s0, t0), (s1, t1) = points[-2], points[-1]
        if abs(t1.contact_speed - target) <= 0.02 * target or t1.contact_speed == t0.contact_speed:
            break
        step = (target - t1.contact_speed) * (s1 - s0) / (t1.contact_speed - t0.contact_speed)
        speed = min(max(LOWEST_SPEED, s1 + step), 2.0 * HIGHEST_SPEED)
        if speed == s1:
            break
    return min((t for _, t in points), key=lambda t: abs(t.contact_speed - target))


@dataclass(frozen=True)
class CheckRow:
    """One trial of the check: stance, fraction of the closed-form speed, trial."""

    stance: str
    fraction: float
    binding: str
    trial: ImpactTrial


def check_against_simulation(
    robot: RobotModel, stances=None, setting: Setting = Setting(), plant: Plant = Plant(),
    source=SCRIPTED,
) -> list[CheckRow]:
    """Trials at BELOW and ABOVE x the closed-form speed of ``setting`` for each stance (None: every
    stance of the robot's description; module docstring), driven by ``source``
    (``trial_at_contact_speed``)."""
    rows = []
    for stance in robot.description.stances if stances is None else stances:
        q = stance_posture(robot, robot.description.stances[stance])
        predicted = closed_form_max_speed(robot, robot.terms(q), NORMAL, setting)
        for fraction in (*BELOW, *ABOVE):
            trial = trial_at_contact_speed(robot, stance, q, fraction * predicted.speed, plant, source)
            rows.append(CheckRow(stance, fraction, predicted.criterion, trial))
    return rows


def _tied_first(row: CheckRow) -> bool:
    """The binding criterion's onset shares the first failure's control step without being named first."""
    times = {CRITERION_OF.get(f): t for f, t in row.trial.failure_times.items()}
    return CRITERION_OF.get(row.trial.first_failure) != row.binding and times.get(row.binding) == row.trial.failure_time


def check_summary(rows: list[CheckRow]) -> dict:
    """Below: trials that fell or slipped (should be none); above: in how many trials the binding
    criterion failed first, in how many its onset tied with the first failure (same control step,
    named second by the order of FAILURES), and in how many it failed at all."""
    below = [r for r in rows if r.fraction < 1.0]
    above = [r for r in rows if r.fraction > 1.0]
    return {
        "below": len(below),
        "below_fell_or_slipped": sum(r.trial.fell or r.trial.slipped or "foot_slip" in r.trial.failures for r in below),
        "below_infeasible": sum(not r.trial.feasible for r in below),
        "above": len(above),
        "above_binding_first": sum(CRITERION_OF.get(r.trial.first_failure) == r.binding for r in above),
        "above_binding_tied": sum(_tied_first(r) for r in above),
        "above_binding_failed": sum(r.binding in {CRITERION_OF.get(f) for f in r.trial.failures} for r in above),
        "above_feasible": sum(r.trial.feasible for r in above),
    }


def check_table(rows: list[CheckRow]) -> str:
    """The check as a Markdown table (onset times in ms from the first wall contact), and its summary line."""
    lines = ["| stance | binds (closed form) | fraction | v cmd (m/s) | v contact (m/s) | slip / lift (mm) | "
             "cone ratio | CoP margin (mm) | capture margin (mm) | max dq/dq_max | failures (onset, ms) | failed first |",
             "|" + "---|" * 12]
    for r in rows:
        t = r.trial
        onsets = ", ".join(f"{name} {1e3 * t.failure_times[name]:.0f}" for name in t.failures) or "-"
        lines.append(
            f"| {r.stance} | {r.binding} | {r.fraction:.2f} | {t.speed:.3f} | {t.contact_speed:.3f} | "
            f"{1e3 * t.foot_slip:.2f} / {1e3 * t.foot_lift:.2f} | {t.cone_ratio:.3f} | {1e3 * t.cop_margin:.1f} | "
            f"{1e3 * t.capture_margin:.1f} | {t.max_velocity_ratio:.2f} | {onsets} | {t.first_failure or '-'} |"
        )
    s = check_summary(rows)
    lines += ["", (
        f"Below: {s['below_fell_or_slipped']} of {s['below']} trials fell or slipped, {s['below_infeasible']} infeasible. "
        f"Above: the binding criterion failed first in {s['above_binding_first']} of {s['above']} trials "
        f"(tied for first in {s['above_binding_tied']} more), failed at all in {s['above_binding_failed']}; "
        f"{s['above_feasible']} stayed feasible."
    )]
    return "\n".join(lines)


def search_table(results: list[StanceMaxSpeed]) -> str:
    """Closed form (each method: speed, binding criterion) and simulated bisection per stance."""
    methods = list(results[0].predicted)
    head = "| stance | " + " | ".join(f"{m} (m/s), binds" for m in methods) + " | simulated v cmd / v contact (m/s) | failed first |"
    lines = [head, "|" + "---|" * (len(methods) + 3)]
    for r in results:
        cells = [f"{p.speed:.3f}, {p.criterion} ({p.where})" if math.isfinite(p.speed) else "inf" for p in r.predicted.values()]
        lines.append(f"| {r.stance} | " + " | ".join(cells)
                     + f" | {r.simulated_reference:.3f} / {r.simulated_contact:.3f} | {r.failed_first or '-'} |")
    return "\n".join(lines)


MARKERS = dict(zip(HELD_CONTACT_CRITERIA, ("o", "s", "^", "D")))


def speed_figure(results: list[StanceMaxSpeed], path: str | Path, title: str) -> Path:
    """The highest feasible contact speed against the stance: the closed form of each method
    (marker: the criterion that binds) and the simulated bisection's contact speed (black bar,
    labelled with what failed first above it); PNG written atomically."""
    fig, ax = plt.subplots(figsize=(7.2, 4.6))
    x = np.arange(len(results))
    methods = list(results[0].predicted)
    for k, method in enumerate(methods):
        offset = (k - (len(methods) - 1) / 2) * 0.15
        for i, r in enumerate(results):
            p = r.predicted[method]
            if math.isfinite(p.speed):
                ax.scatter(x[i] + offset, p.speed, marker=MARKERS[p.criterion], color=f"C{k}", s=60,
                           label=method if i == 0 else None, zorder=3)
    for i, r in enumerate(results):
        ax.hlines(r.simulated_contact, x[i] - 0.35, x[i] + 0.35, color="k", lw=2.5,
                  label="simulated (bisection)" if i == 0 else None)
        ax.annotate(r.failed_first or "none failed", (x[i], r.simulated_contact), textcoords="offset points",
                    xytext=(0, -12), ha="center", fontsize=7)
    for criterion, marker in MARKERS.items():
        ax.scatter([], [], marker=marker, color="0.4", label=f"binds: {criterion}")
    ax.set_xticks(x, [r.stance for r in results])
    ax.set(xlabel="stance", ylabel="highest feasible contact speed (m/s)", title=title)
    ax.set_ylim(bottom=0.0)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    try:
        return write_atomic(Path(path), lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    finally:
        plt.close(fig)
