"""The check of a floating base's closed-form highest feasible speed against simulation, and the
report of its stance search (``scenarios.max_speed_search.search_stance``; docs/floating-base.md;
results: docs/results.md).

Trials at contact speeds :data:`BELOW` x the closed-form speed must neither fall nor slip (a slip
onset or a foot frame moved beyond 5 mm); at :data:`ABOVE` x (20 % and more above it) the binding
criterion should be the failure seen first in the majority of trials (:data:`CRITERION_OF`: each
measured failure is the closed form's criterion of the same name; a fall is none of them). A
contact speed is reached by a secant search on the commanded speed (the servo lags the command).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.robot import RobotModel  # noqa: E402
from impactqp.controller.model.humanoid_stance import stance_posture  # noqa: E402
from impactqp.controller.model.max_speed import HELD_CONTACT_CRITERIA, Setting, closed_form_max_speed  # noqa: E402
from impactqp.sim.runner import NORMAL  # noqa: E402
from impactqp.sim.trial_result import TrialResult  # noqa: E402
from impactqp.sim.trial_sources import SCRIPTED  # noqa: E402

from .max_speed_search import STANCE_HIGHEST_SPEED, STANCE_LOWEST_SPEED, StancePlant  # noqa: E402
from .stance_evaluation import StanceMaxSpeed  # noqa: E402

BELOW = (0.5, 0.8, 0.95)
ABOVE = (1.2, 1.3, 1.4)
SECANT_STEPS = 6
# a failure seen in simulation and the closed-form criterion it measures (a fall measures none)
CRITERION_OF = {criterion: criterion for criterion in HELD_CONTACT_CRITERIA}


def trial_at_contact_speed(
    robot, stance: str, q: np.ndarray, target: float, plant: StancePlant, source=SCRIPTED
) -> TrialResult:
    """A trial whose measured contact speed is ``target`` within 2 % (secant on the commanded
    speed within [STANCE_LOWEST_SPEED, 2 STANCE_HIGHEST_SPEED], at most SECANT_STEPS trials; the closest one
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
        speed = min(max(STANCE_LOWEST_SPEED, s1 + step), 2.0 * STANCE_HIGHEST_SPEED)
        if speed == s1:
            break
    return min((t for _, t in points), key=lambda t: abs(t.contact_speed - target))


@dataclass(frozen=True)
class CheckRow:
    """One trial of the check: stance, fraction of the closed-form speed, trial."""

    stance: str
    fraction: float
    binding: str
    trial: TrialResult


def check_against_simulation(
    robot: RobotModel, stances=None, setting: Setting = Setting(), plant: StancePlant = StancePlant(),
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
    named second by the order of the criteria, ``sim.observed_criteria``), and in how many it failed at all."""
    below = [r for r in rows if r.fraction < 1.0]
    above = [r for r in rows if r.fraction > 1.0]
    return {
        "below": len(below),
        "below_fell_or_slipped": sum(r.trial.fell or r.trial.held.slipped or "foot_slip" in r.trial.failures for r in below),
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
            f"| {r.stance} | {r.binding} | {r.fraction:.2f} | {t.normal_speed:.3f} | {t.contact_speed:.3f} | "
            f"{1e3 * t.held.foot_slip:.2f} / {1e3 * t.held.foot_lift:.2f} | {t.cone_ratio:.3f} | {1e3 * t.cop_margin:.1f} | "
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
