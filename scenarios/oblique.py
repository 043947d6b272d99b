"""The frictional impact law against MuJoCo's simulated wall: oblique impacts of a fixed-base arm
(``impactqp oblique``, ``docs/frictional-impacts.md``, "Against MuJoCo").

Trials (:class:`ObliqueGrid`): the grid v_t / v_n in {0, 0.25, 0.5, 0.75, 1} x mu in {0.1, 0.3,
0.6} x the robot's first two named postures at v_n = 0.12 m/s, plus the paper's conditions (v_n =
0.12 m/s, v_t = 0.03 .. 0.12 m/s on the first posture, at the default wall's mu = 0.1123). The
tangential velocity lies along the surface tangent t = normalise(n x e_z) of ``sim.generation``.
Each trial: the plain Cartesian approach (``sim.trial_sources.CartesianApproach``: no QP, the
tool hits at the commanded velocity) on the scene whose wall has the trial's mu (the Surface's
``friction``: MuJoCo's tool/wall pair, elliptic cone, condim 3; MuJoCo's noslip post-processing
on, ``sim.scene.NOSLIP_ITERATIONS``, so that a contact inside its cone sticks instead of
creeping), started 2 cm before the wall at
the commanded velocity, on the default plant or another (``sim.plant``: e.g. a joint impedance
servo, ``servo_stiffness``; docs/frictional-impacts.md, "Whose W the simulated arm has").

Measured (``controller.measured.oblique_impact``): the impulse of the contact's compression and
restitution, its tangential part p_t, the post-impact tangential contact velocity v_t+, the
least tangential speed along the impact and the observed mode. Predicted, for CRB, GM and the
classical law: ``frictional_impulse(W, n, v-, mu, e = 0)`` with the predictor's inverse inertia
W (``controller.model.prediction.inverse_inertia``) at the pre-impact state (q-, dq-),
v- = J(q-) dq-: p_t, v_t+, the law's own mode (``law_mode``) and its least tangential speed
(:func:`law_row`). On a plant with a joint impedance (``servo_stiffness``) a fourth predictor,
"impedance": the law with the held arm's W_K(T) from the model
(``controller.model.impedance_inverse_inertia``: the arm linearised at q-, held by the plant's
stiffness K, critically damped, over a half-sine pulse of T = ``IMPACT_DURATION``); and two
more: "press", the steady press of the held arm whose command goes on into the wall
(``controller.model.press_slide``, at q-, under the trial's commanded contact velocity), and
"held", the impedance row with v_t+ the press's where the simulated contact was still closed when
v_t+ was read (a window not ended by a separation: the regime is read from the simulation, not
predicted; :func:`held_row`). ``impactqp oblique`` adds the reference row "plant", the same law
with the simulated plant's own W over the same pulse (``scenarios.oblique_inertia.with_plant_row``).

A predicted v_t+ **agrees** when |v_t+ predicted - v_t+ simulated| <= max(20 % |v_t+ simulated|,
0.01 m/s). A predicted mode **agrees** when the law's path, read by the simulation's rule
(``oblique_impact.observed_mode``: stopped when its least tangential speed is at most
``STICK_SPEED``), gives the simulated mode; the law's own mode, at its own resolution, is kept
beside it. The summary gives, per predictor and series (grid, paper, all), the share (%) of
trials whose mode agrees, whose v_t+ agrees and whose law's own mode is the simulated one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.measured.oblique_impact import measure_oblique_impact, observed_mode, tangential_part
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.frictional_impact import frictional_impulse
from impactqp.controller.model.impedance_inverse_inertia import impedance_inverse_inertia
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.prediction import FRICTIONAL_METHODS, inverse_inertia
from impactqp.controller.model.press_slide import contact_compliance, press_slide
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.generation import tangential_direction
from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import ProcessPool
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.scene import NOSLIP_ITERATIONS, Scene, build_scene
from impactqp.sim.trial_sources import CARTESIAN

from .campaign import PAPER_TANGENTIAL_SPEEDS, TANGENTIAL_NORMAL_SPEED

NORMAL_SPEED = TANGENTIAL_NORMAL_SPEED
"""m/s: every trial's commanded normal speed (the paper's tangential series')."""
VELOCITY_SHARE = 0.2
VELOCITY_FLOOR = 0.01
"""m/s: a predicted v_t+ agrees within max(VELOCITY_SHARE |v_t+ simulated|, VELOCITY_FLOOR)."""
RESTITUTION = 0.0
"""The predictions' restitution e (energetic): MuJoCo's contact pair is critically damped."""
IMPACT_DURATION = 0.015
"""s: T, the pulse over which a held arm's W is taken, the "impedance" row's (module docstring) and
the reference row "plant"'s: as long as the study's impacts (windows of 10 to 20 ms,
docs/frictional-impacts.md)."""
POSTURES = 2
"""The grid's postures: the robot's first named ones."""
SERIES = ("grid", "paper")


@dataclass(frozen=True)
class ObliqueTrial:
    """One trial: its ``series`` ("grid" or "paper"), posture, commanded normal speed v_n and
    tangential speed v_t (m/s, along the surface tangent) and the wall's friction mu."""

    series: str
    posture: str
    normal_speed: float
    tangential_speed: float
    friction: float


@dataclass(frozen=True)
class ObliqueGrid:
    """The trials of a study (module docstring): tangential-to-normal speed ratios x frictions x
    the robot's first ``postures`` named postures, plus the paper's tangential speeds (m/s) on
    the first posture at the default wall's friction."""

    ratios: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
    frictions: tuple[float, ...] = (0.1, 0.3, 0.6)
    postures: int = POSTURES
    paper_speeds: tuple[float, ...] = PAPER_TANGENTIAL_SPEEDS

    def trials(self, choice: RobotChoice) -> list[ObliqueTrial]:
        names = tuple(choice.robot.postures)[: self.postures]
        grid = [
            ObliqueTrial("grid", name, NORMAL_SPEED, ratio * NORMAL_SPEED, mu)
            for name in names for mu in self.frictions for ratio in self.ratios
        ]
        paper = [ObliqueTrial("paper", names[0], NORMAL_SPEED, v_t, DEFAULT_WALL.friction) for v_t in self.paper_speeds]
        return grid + paper


GRIDS = {
    "full": ObliqueGrid(),
    "small": ObliqueGrid(ratios=(0.0, 1.0), frictions=(0.3,), postures=1, paper_speeds=(0.06,)),
}
"""The named grids of ``impactqp oblique --grid``: the study's, and a small one for a quick run."""


def grid_named(name: str) -> ObliqueGrid:
    if name not in GRIDS:
        raise BadInputError(f"unknown grid {name!r}; choose from {', '.join(GRIDS)}")
    return GRIDS[name]


def fixed_base(choice: RobotChoice) -> RobotChoice:
    """``choice``, whose robot must be a fixed-base arm (bad input otherwise)."""
    if choice.robot.floating:
        raise BadInputError(f"the oblique study runs a fixed-base arm, not the {choice.robot.name}")
    return choice


class ObliqueTrials:
    """Runs :class:`ObliqueTrial` trials of ``choice``'s arm on ``plant`` (None: the default
    plant): one scene per wall friction (built on first use), each trial measured and predicted
    as a JSON-ready row (:meth:`run`)."""

    def __init__(self, choice: RobotChoice, plant: PlantParameters | None = None):
        self.choice, self.robot, self.plant = fixed_base(choice), choice.model(), plant
        self.scenes: dict[float, Scene] = {}

    def scene(self, friction: float) -> Scene:
        if friction not in self.scenes:
            surface = Surface(DEFAULT_WALL.point, DEFAULT_WALL.normal, friction)
            self.scenes[friction] = build_scene(surface, self.plant, robot=self.choice.robot, tool=self.choice.tool,
                                                noslip_iterations=NOSLIP_ITERATIONS)
        return self.scenes[friction]

    def run(self, trial: ObliqueTrial) -> dict:
        """The trial's row: its settings, the simulated impact and each predictor's."""
        scene, normal = self.scene(trial.friction), DEFAULT_WALL.normal
        tangential = trial.tangential_speed * tangential_direction(normal)
        spec = TrialSpec(trial.posture, self.choice.posture(trial.posture).q, trial.normal_speed, tangential)
        measured = measure_oblique_impact(run_approach(scene, self.robot, spec, CARTESIAN).log, self.robot, normal)
        step = scene.timestep
        simulated = {
            "contact_speed": float(-normal @ measured.pre_velocity),
            "pre_tangential": measured.pre_tangential.tolist(), "normal_impulse": measured.normal_impulse,
            "tangential_impulse": measured.tangential_impulse.tolist(),
            "post_tangential": measured.post_tangential.tolist(),
            "post_normal_speed": float(normal @ measured.post_velocity), "mode": measured.mode,
            "least_tangential_speed": measured.least_tangential_speed,
            "end_rule": measured.end_rule, "window": (measured.end + 1 - measured.start) * step,
        }
        terms = self.robot.terms(measured.q_pre, measured.dq_pre, check_limits=False)
        predicted = {
            method: law_row(inverse_inertia(method, terms, normal, RESTITUTION), measured.pre_velocity, trial.friction,
                            simulated)
            for method in FRICTIONAL_METHODS
        }
        stiffness = () if self.plant is None else self.plant.servo_stiffness
        if stiffness:
            W = impedance_inverse_inertia(terms, stiffness, IMPACT_DURATION)
            predicted["impedance"] = law_row(W, measured.pre_velocity, trial.friction, simulated)
            commanded = tangential - trial.normal_speed * normal
            predicted["press"] = press_row(contact_compliance(terms, stiffness), commanded, trial.friction, simulated)
            predicted["held"] = held_row(predicted["impedance"], predicted["press"], simulated)
        return {
            "series": trial.series, "posture": trial.posture, "normal_speed": trial.normal_speed,
            "tangential_speed": trial.tangential_speed, "friction": trial.friction,
            "simulated": simulated, "predicted": predicted,
        }


def law_row(W: np.ndarray, pre_velocity: np.ndarray, friction: float, simulated: dict) -> dict:
    """The frictional law with inverse inertia ``W`` at the wall (``frictional_impulse``, e =
    ``RESTITUTION``) from the pre-impact contact velocity v-, read as the simulation is
    (``observed_mode``) and against the ``simulated`` row's mode and v_t+ (module docstring)."""
    normal = DEFAULT_WALL.normal
    impact = frictional_impulse(W, normal, pre_velocity, friction, RESTITUTION)
    post = tangential_part(impact.post_velocity, normal)
    mode = observed_mode(impact.least_tangential_speed, float(np.linalg.norm(post)))
    return {
        "normal_impulse": float(normal @ impact.impulse),
        "tangential_impulse": tangential_part(impact.impulse, normal).tolist(),
        "post_tangential": post.tolist(), "mode": mode, "law_mode": impact.mode, "mu_bar": impact.mu_bar,
        "least_tangential_speed": impact.least_tangential_speed,
        "mode_agrees": mode == simulated["mode"],
        "velocity_agrees": velocity_agrees(post, np.asarray(simulated["post_tangential"])),
    }


def press_row(compliance: np.ndarray, commanded: np.ndarray, friction: float, simulated: dict) -> dict:
    """The steady press (``press_slide``) of the contact of ``compliance`` under the trial's
    commanded contact velocity, as a predictor's row against the ``simulated`` one: its mode
    (a slide read as "slip"), its tangential velocity as v_t+, its force rate's normal and
    tangential parts (N/s; where a law's row has its impulse's)."""
    normal = DEFAULT_WALL.normal
    press = press_slide(compliance, normal, commanded, friction)
    mode = "slip" if press.mode == "slide" else press.mode
    post = press.velocity  # tangential: the press stays on the wall
    return {
        "normal_force_rate": float(normal @ press.force_rate),
        "tangential_force_rate": tangential_part(press.force_rate, normal).tolist(),
        "post_tangential": post.tolist(), "mode": mode, "law_mode": mode, "mu_bar": None,
        "least_tangential_speed": float(np.linalg.norm(post)), "mode_agrees": mode == simulated["mode"],
        "velocity_agrees": velocity_agrees(post, np.asarray(simulated["post_tangential"])),
    }


def held_row(impact: dict, press: dict, simulated: dict) -> dict:
    """The held arm's row: the ``impact`` law's (its mode, impulse and v_t+), with v_t+ the
    ``press``'s where the simulated contact was still closed when v_t+ was read (its window ended
    at a force minimum or at the log's end, not at a separation: the tool pressed on the wall, as
    the press has it; module docstring)."""
    if simulated["end_rule"] == "separation":
        return {**impact, "post_from": "impact"}
    post = np.asarray(press["post_tangential"])
    return {**impact, "post_from": "press", "post_tangential": post.tolist(),
            "velocity_agrees": velocity_agrees(post, np.asarray(simulated["post_tangential"]))}


def velocity_agrees(predicted: np.ndarray, simulated: np.ndarray) -> bool:
    """|predicted - simulated| <= max(VELOCITY_SHARE |simulated|, VELOCITY_FLOOR) (module docstring)."""
    bound = max(VELOCITY_SHARE * float(np.linalg.norm(simulated)), VELOCITY_FLOOR)
    return bool(np.linalg.norm(np.asarray(predicted) - np.asarray(simulated)) <= bound)


def summary(rows: list[dict]) -> dict:
    """Per series (and "all", and the grid per wall friction: "mu = 0.1", ...) and predictor:
    trials, the share (%) whose mode agrees, whose v_t+ agrees and whose law's own mode is the
    simulated one (module docstring)."""
    methods = list(rows[0]["predicted"]) if rows else []
    groups = {series: [r for r in rows if series in ("all", r["series"])] for series in (*SERIES, "all")}
    for mu in sorted({r["friction"] for r in rows if r["series"] == "grid"}):
        groups[f"mu = {mu:g}"] = [r for r in rows if r["series"] == "grid" and r["friction"] == mu]
    result = {}
    for series, chosen in groups.items():
        if not chosen:
            continue
        result[series] = {
            method: {
                "trials": len(chosen),
                "mode_agreement": 100.0 * np.mean([r["predicted"][method]["mode_agrees"] for r in chosen]),
                "velocity_agreement": 100.0 * np.mean([r["predicted"][method]["velocity_agrees"] for r in chosen]),
                "law_mode_agreement": 100.0 * np.mean(
                    [r["predicted"][method]["law_mode"] == r["simulated"]["mode"] for r in chosen]),
            }
            for method in methods
        }
    return result


# ---------------------------------------------------------------------------- processes
_WORKER: ObliqueTrials | None = None


def _init_worker(choice: RobotChoice, plant: PlantParameters | None) -> None:
    global _WORKER
    _WORKER = ObliqueTrials(choice, plant)


def _run_in_worker(trial: ObliqueTrial) -> dict:
    return _WORKER.run(trial)


def run_oblique_study(choice: RobotChoice, grid: ObliqueGrid, jobs: int = 1, plant: PlantParameters | None = None) -> dict:
    """The study of ``choice``'s arm on ``plant`` (None: the default plant) over ``grid`` on
    ``jobs`` processes: its JSON report (robot, tool, the plant's servo, rules, rows in the order
    of the grid's trials, summary)."""
    trials = grid.trials(fixed_base(choice))
    with ProcessPool(jobs, _init_worker, (choice, plant)) as pool:
        rows = list(pool.map(_run_in_worker, trials))
    return {
        "robot": choice.robot.name, "tool": choice.tool.name, "servo": servo_name(plant),
        "normal": DEFAULT_WALL.normal.tolist(),
        "restitution": RESTITUTION, "velocity_share": VELOCITY_SHARE, "velocity_floor": VELOCITY_FLOOR,
        "rows": rows, "summary": summary(rows),
    }


def servo_name(plant: PlantParameters | None) -> str:
    """The servo of ``plant`` in words: its joint impedance or its computed-torque bandwidth."""
    plant = PlantParameters() if plant is None else plant
    if plant.servo_stiffness:
        return "joint impedance K = " + ", ".join(f"{k:g}" for k in plant.servo_stiffness) + " N m/rad"
    return f"computed torque, {plant.servo_gain:g} rad/s"


def markdown(report: dict) -> str:
    """The report as Markdown: the summary, then one line per trial (speeds in mm/s, |p_t| / p_n
    the tangential impulse's share of the normal one (a press's: its force rate's), least: the least tangential speed along the
    impact; a predicted mode the law's own differs from shows it after a slash; ✗: the mode, or
    v_t+, does not agree)."""
    lines = [f"# Oblique impacts: the {report['robot']} against MuJoCo (servo: {report['servo']})", "",
             "| series | predictor | trials | mode agrees | v_t+ agrees | law's own mode agrees |", "|---|---|---|---|---|---|"]
    for series, methods in report["summary"].items():
        for method, s in methods.items():
            lines.append(f"| {series} | {method} | {s['trials']} | {s['mode_agreement']:.0f} % "
                         f"| {s['velocity_agreement']:.0f} % | {s['law_mode_agreement']:.0f} % |")
    methods = list(report["rows"][0]["predicted"]) if report["rows"] else []
    lines += ["", "| series | posture | mu | v_t | sim mode | sim least | sim \\|p_t\\|/p_n | sim \\|v_t+\\| | "
              + " | ".join(f"{m} mode | {m} least | {m} \\|p_t\\|/p_n | {m} \\|v_t+\\|" for m in methods) + " |",
              "|" + "---|" * (8 + 4 * len(methods))]
    for row in report["rows"]:
        sim = row["simulated"]
        cells = [row["series"], row["posture"], f"{row['friction']:g}", f"{1e3 * row['tangential_speed']:.0f}",
                 sim["mode"], _least(sim), _share(sim), _speed(sim)]
        for m in methods:
            p = row["predicted"][m]
            mode = p["mode"] if p["law_mode"] == p["mode"] else f"{p['mode']} / {p['law_mode']}"
            cells += [mode + ("" if p["mode_agrees"] else " ✗"), _least(p), _share(p),
                      _speed(p) + ("" if p["velocity_agrees"] else " ✗")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _share(entry: dict) -> str:
    """|p_t| / p_n, or a press's |f'_t| / f'_n."""
    part = "impulse" if "normal_impulse" in entry else "force_rate"
    return f"{np.linalg.norm(entry[f'tangential_{part}']) / entry[f'normal_{part}']:.3f}"


def _least(entry: dict) -> str:
    return f"{1e3 * entry['least_tangential_speed']:.1f}"


def _speed(entry: dict) -> str:
    return f"{1e3 * np.linalg.norm(entry['post_tangential']):.1f}"
