"""The robust friction rows against MuJoCo: oblique impacts at the QP's own highest speed
(``impactqp oblique --qp-speed``, ``docs/frictional-impacts.md``, "At the QP's own highest
speed").

Trials (:class:`QpSpeedGrid`): per fixed-base arm, tangential-to-normal speed ratios r in {0,
0.25, 0.5, 0.75, 1} x wall frictions mu in {0.1, 0.3, 0.6} x the robot's first two named
postures. The tangential velocity lies along the wall's tangent t = normalise(n x e_z)
(``sim.generation``), v_t = r v_ref t, v_ref the closed form of the robust rows sliding at
v_t = 0 (``friction_max_speed.frictional_max_speed`` at the named posture, the smallest over the
controller's predictors): the approach's own ratio is measured, v_t- / v_c.

Each trial runs twice on the scene whose wall has the trial's mu (``sim.scene``: the tool/wall
pair, elliptic cone, condim 3; noslip on, the oblique study's scene, ``ObliqueTrials.scene``), each the QP-limited run of ``scenarios.max_speed_search``: the
arm starts at rest ``qp_start_distance`` from the wall and its QP (``sim.trial_sources.QpCommand``,
posture weight 0, the commanded state) is asked for a normal speed of ``QP_REQUEST_SPEED``
(2 m/s) plus v_t: the impact rows cap the normal speed at the QP's own highest one.

- ``robust``: the controller's impact rows with the robust friction rows of the wall's mu (the
  4-edge pyramid, ``FrictionRows(mu)``);
- ``normal``: the same rows without friction rows (eq. 12's normal impulse only).

Observed (``scenarios.trial.TrialRunner.evaluate``): the contact speed v_c, the pre-impact
tangential contact speed, the largest |dq_i| / dq_max_i over the 50 ms after the contact start
and its joint, the impulsive torque ratio, and whether a limit broke (either ratio above 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.constraints import jump_model_names
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.friction_pyramid import FrictionRows
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.max_speed import Setting
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.generation import tangential_direction
from impactqp.sim.process_pool import ProcessPool
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.trial_sources import QpCommand

from .max_speed_search import LOWEST_SPEED, QP_REQUEST_SPEED, qp_start_distance
from .oblique import POSTURES, ObliqueTrials, fixed_base
from .trial import ACCELERATION_ALLOWANCE, TrialRunner

ROWS = ("robust", "normal")
"""The two controllers of every trial: with the robust friction rows, and with the normal-only rows."""
DURATION_SPEED_SHARE = 0.5
"""The trial's simulated time allows the approach at this share of the expected (closed-form) speed
(at least ``max_speed_search.LOWEST_SPEED``)."""


@dataclass(frozen=True)
class QpSpeedTrial:
    """One trial: posture, the tangential-to-normal ratio r, the wall's mu and v_t (m/s, along the
    wall's tangent)."""

    posture: str
    ratio: float
    friction: float
    tangential_speed: float


@dataclass(frozen=True)
class QpSpeedGrid:
    """The trials of a campaign (module docstring): ratios x frictions x the robot's first
    ``postures`` named postures; ``jump_model`` the controllers' impact rows."""

    ratios: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
    frictions: tuple[float, ...] = (0.1, 0.3, 0.6)
    postures: int = POSTURES
    jump_model: str = "crb"

    def trials(self, choice: RobotChoice) -> list[QpSpeedTrial]:
        robot = fixed_base(choice).model()
        trials = []
        for name in tuple(choice.robot.postures)[: self.postures]:
            terms = robot.terms(choice.posture(name).q)
            for mu in self.frictions:
                reference = robust_speed(robot, terms, np.zeros(3), self.jump_model, mu)
                trials += [QpSpeedTrial(name, r, mu, r * reference) for r in self.ratios]
        return trials


QP_SPEED_GRIDS = {
    "full": QpSpeedGrid(),
    "small": QpSpeedGrid(ratios=(0.5,), frictions=(0.3,), postures=1),
}
"""The grids of ``impactqp oblique --qp-speed --grid``: the campaign's and a quick one (1 trial)."""


def robust_speed(robot, terms, tangential: np.ndarray, jump_model: str, friction: float) -> float:
    """The closed-form highest normal speed of the rows of ``jump_model`` (every predictor of it)
    with the friction rows of ``friction`` (0: normal-only), sliding at ``tangential``."""
    rows = FrictionRows(friction)
    return min(
        frictional_max_speed(robot, terms, DEFAULT_WALL.normal, tangential, Setting(name), rows).max_speed.speed
        for name in jump_model_names(jump_model)
    )


class QpSpeedTrials(ObliqueTrials):
    """Runs :class:`QpSpeedTrial` trials of ``choice``'s arm with the QP of ``jump_model`` in the
    loop: one scene per wall friction, each trial a JSON-ready row (:meth:`run`)."""

    def __init__(self, choice: RobotChoice, jump_model: str):
        super().__init__(choice)
        self.jump_model = jump_model

    def run(self, trial: QpSpeedTrial) -> dict:
        """The trial's row: its settings and, per controller of ``ROWS``, what was observed."""
        return {
            "posture": trial.posture, "ratio": trial.ratio, "friction": trial.friction,
            "tangential_speed": trial.tangential_speed,
            "runs": {rows: self.observe(trial, rows) for rows in ROWS},
        }

    def observe(self, trial: QpSpeedTrial, rows: str) -> dict:
        """The QP-limited run of the controller ``rows`` (module docstring) and what it observed."""
        scene, normal = self.scene(trial.friction), DEFAULT_WALL.normal
        friction = trial.friction if rows == "robust" else 0.0
        q = self.choice.posture(trial.posture).q
        tangential = trial.tangential_speed * tangential_direction(normal)
        expected = robust_speed(self.robot, self.robot.terms(q), tangential, self.jump_model, friction)
        spec = TrialSpec(trial.posture, q, QP_REQUEST_SPEED, tangential, jump_model=self.jump_model,
                         start_at_rest=True, start_distance=qp_start_distance(expected))
        source = QpCommand(method=self.jump_model, posture_weight=0.0, friction=friction)
        approach = DURATION_SPEED_SHARE * max(expected, LOWEST_SPEED)
        duration = ACCELERATION_ALLOWANCE + spec.start_distance / approach + spec.after_contact
        run = run_approach(scene, self.robot, spec, source, duration)
        result = TrialRunner(scene, self.robot, source).evaluate(spec, run.log, run.driver.controller.fallback_count)
        v_pre = self.robot.terms(result.impact.q_pre, check_limits=False).J @ result.impact.dq_pre
        return {
            "contact_speed": result.contact_speed,
            "pre_tangential_speed": float(np.linalg.norm(v_pre - (normal @ v_pre) * normal)),
            "closed_form_speed": expected,
            "max_velocity_ratio": result.max_velocity_ratio, "max_velocity_joint": result.max_velocity_joint,
            "max_torque_ratio": result.max_torque_ratio, "violated": result.violated,
            "fallbacks": result.fallback_count,
        }


def summary(rows: list[dict]) -> dict:
    """Per controller: trials, how many broke a limit, the largest velocity and torque ratios and
    the median contact speed (m/s)."""
    return {
        name: {
            "trials": len(rows),
            "violated": sum(r["runs"][name]["violated"] for r in rows),
            "max_velocity_ratio": max(r["runs"][name]["max_velocity_ratio"] for r in rows),
            "max_torque_ratio": max(r["runs"][name]["max_torque_ratio"] for r in rows),
            "median_contact_speed": float(np.median([r["runs"][name]["contact_speed"] for r in rows])),
        }
        for name in ROWS
    }


# ---------------------------------------------------------------------------- processes
_WORKER: QpSpeedTrials | None = None


def _init_worker(choice: RobotChoice, jump_model: str) -> None:
    global _WORKER
    _WORKER = QpSpeedTrials(choice, jump_model)


def _run_in_worker(trial: QpSpeedTrial) -> dict:
    return _WORKER.run(trial)


def run_qp_speed_campaign(choice: RobotChoice, grid: QpSpeedGrid, jobs: int = 1) -> dict:
    """The campaign of ``choice``'s arm over ``grid`` on ``jobs`` processes: its JSON report."""
    trials = grid.trials(choice)
    with ProcessPool(jobs, _init_worker, (choice, grid.jump_model)) as pool:
        rows = list(pool.map(_run_in_worker, trials))
    return {
        "robot": choice.robot.name, "tool": choice.tool.name, "normal": DEFAULT_WALL.normal.tolist(),
        "jump_model": grid.jump_model, "request_speed": QP_REQUEST_SPEED, "rows": rows, "summary": summary(rows),
    }


def qp_speed_grid_named(name: str, jump_model: str) -> QpSpeedGrid:
    """The named grid with the controllers' ``jump_model`` (bad input when either is unknown)."""
    if name not in QP_SPEED_GRIDS:
        raise BadInputError(f"unknown grid {name!r}; choose from {', '.join(QP_SPEED_GRIDS)}")
    jump_model_names(jump_model)
    if jump_model == "classical_normal":
        raise BadInputError("the classical_normal model keeps the normal impulse only: it has no friction rows")
    grid = QP_SPEED_GRIDS[name]
    return QpSpeedGrid(grid.ratios, grid.frictions, grid.postures, jump_model)


def markdown(report: dict) -> str:
    """The report as Markdown: the summary, then one line per trial (speeds in mm/s)."""
    lines = [f"# Oblique impacts at the QP's own highest speed: the {report['robot']}, {report['jump_model']} rows", "",
             "| rows | trials | broke a limit | largest \\|dq\\|/dq_max | largest torque ratio | median v_c (mm/s) |",
             "|---|---|---|---|---|---|"]
    for name, s in report["summary"].items():
        lines.append(f"| {name} | {s['trials']} | {s['violated']} | {s['max_velocity_ratio']:.3f} "
                     f"| {s['max_torque_ratio']:.3f} | {1e3 * s['median_contact_speed']:.0f} |")
    lines += ["", "| posture | mu | v_t | " + " | ".join(
        f"{name} v_c | {name} v_t-/v_c | {name} \\|dq\\|/dq_max | {name} torque ratio" for name in ROWS) + " |",
        "|" + "---|" * (3 + 4 * len(ROWS))]
    for row in report["rows"]:
        cells = [row["posture"], f"{row['friction']:g}", f"{1e3 * row['tangential_speed']:.0f}"]
        for name in ROWS:
            run = row["runs"][name]
            cells += [f"{1e3 * run['contact_speed']:.0f}", _ratio(run),
                      f"{run['max_velocity_ratio']:.3f} {run['max_velocity_joint']}{_broken(run['max_velocity_ratio'])}",
                      f"{run['max_torque_ratio']:.3f}{_broken(run['max_torque_ratio'])}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _broken(ratio: float) -> str:
    return " ✗" if ratio > 1.0 else ""


def _ratio(run: dict) -> str:
    speed = run["contact_speed"]
    return f"{run['pre_tangential_speed'] / speed:.2f}" if speed > 0.0 else "nan"

