"""Diagnose the gap between measured impacts and the simulation: replay, compare, fit causes.

Pipeline (``diagnose``):

1. **Measure.** Every trial of the dataset is checked (``controller.measured.dataset.validate``); bad trials are
   skipped with their reasons. The impact is detected and the jump extracted with the same
   function as for simulated data (``controller.measured.impact.measure_impact``); the impulse is integrated
   where a force log exists.
2. **Replay.** Each trial is replayed in the simulation from the logged state ``REPLAY_LEAD``
   control steps before the impact (q, and dq averaged over 5 samples against encoder noise),
   on the dataset's surface, with the logged ``dq_cmd`` driving the joint servo, until
   ``REPLAY_TAIL`` steps after the detection. The servo's reference at that sample is rebuilt
   from the log start and the commands before it (``servo_reference_from_commands``), so a
   plant that lags behind its commands (joint damping) lags in the replay as it did. The replayed impact is measured with the same
   function. The classical, GM and CRB predictions are evaluated at the logged pre-impact state
   (v- = J dq-, c_r = 0).
3. **Compare.** Errors (25) and average errors (26) of the nominal simulation per joint, posture
   and speed; their sign (the least-squares ratio of simulated to measured jump per joint,
   > 1: the simulation overshoots) and their scaling with speed (slope of (26) against the
   reference speed); the share of the error carried by each joint.
4. **Extend.** Each candidate cause (``sim.causes``) is fitted by bounded least squares over
   the replays (sum of squared residuals minimised by ``scipy.optimize.minimize``, Powell), with K-fold cross-validation over trials
   (K = min(3, trials)). The fit's residuals per trial are the jump error (7) / SIGMA_JUMP, the
   error of the mean joint torque over the ``TORQUE_WINDOW`` samples before contact (7) /
   SIGMA_TORQUE, and, with force data, the impulse error (3) / SIGMA_IMPULSE and the contact
   duration error / SIGMA_DURATION. The nominal value and a coarse grid
   over the bounds, evaluated once on all trials, give each fold's starting point.
5. **Name the cause.** The held-out error of a candidate is the mean over trials of (26) between
   the replay with the parameters fitted without that trial's fold and the measured jump. Its
   gain is 1 - heldout / baseline, the baseline being the nominal replay's (26). The cause is the
   candidate with the largest gain; ``explained`` is true only when that gain reaches
   ``EXPLAINED_GAIN`` (30 %).
6. **Measure the gain.** ``baseline_error`` and ``extended_error`` (the cause's held-out error).
   The cause's parameters are refitted on all trials (plant-override keys).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from impactqp.controller.model.jump import JUMP_MODELS, METHODS, average_prediction_error
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import NQ, PandaModel

from .causes import Cause, default_causes
from impactqp.controller.measured.dataset import read_dataset, validate
from impactqp.controller.measured.impact import ImpactNotFoundError, measure_impact
from .plant import PlantParameters
from .runner import CommandReplay, SimulationUnstableError, run_trial, servo_reference_from_commands
from .scene import build_scene
from impactqp.controller.model.validation import BadInputError

REPLAY_LEAD = 40
REPLAY_TAIL = 30
START_AVERAGE = 2  # dq at the replay start: mean of samples i0 - 2 .. i0 + 2 (within the log)
TORQUE_SETTLE = 10  # samples after the replay start before the torque window may begin
TORQUE_WINDOW = 30  # mean tau over the 30 samples ending 2 samples before the pre-impact one
SIGMA_JUMP = 0.005
SIGMA_TORQUE = 0.05
SIGMA_IMPULSE = 0.02
SIGMA_DURATION = 1e-3
EXPLAINED_GAIN = 0.30
GRID_POINTS = {1: 7, 2: 5}
MAX_FOLDS = 3
FIT_XTOL = 2e-3
FIT_MAX_EVALUATIONS = 30  # per fitted parameter, for the fit on all trials
FOLD_MAX_EVALUATIONS = 15  # per fitted parameter, for each cross-validation fold


@dataclass
class MeasuredTrial:
    """What the diagnosis needs of one valid trial."""

    id: str
    posture: str | None
    reference_speed: float
    tangential_speed: float
    q0: np.ndarray
    dq0: np.ndarray
    servo_reference: tuple[np.ndarray, np.ndarray]
    dq_cmd: np.ndarray
    control_period: float
    jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None
    torque: np.ndarray
    q_pre: np.ndarray
    dq_pre: np.ndarray
    torque_window: tuple[int, int]  # samples of the replay whose torque is averaged


@dataclass(frozen=True)
class ReplayFeatures:
    jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None
    torque: np.ndarray


def load_trials(directory: str | Path) -> tuple[list[MeasuredTrial], list[dict], Surface]:
    """Valid trials ready for replay, the skipped ones with their reasons, and the surface."""
    directory = Path(directory)
    problems = validate(directory)
    bad = {k for k, v in problems.items() if k != "dataset" and v}
    dataset = read_dataset(directory, skip=bad, strict=False)
    skipped = [{"id": k, "reason": "; ".join(problems[k])} for k in sorted(bad)]
    skipped += [{"id": "dataset", "reason": p} for p in problems["dataset"]]
    trials = []
    period = dataset.header.control_period
    for trial in dataset.trials:
        log, entry = trial.log, trial.entry
        try:
            impact = measure_impact(log)
        except ImpactNotFoundError as error:
            skipped.append({"id": entry.id, "reason": f"no impact found: {error}"})
            continue
        i0 = max(impact.pre_index - REPLAY_LEAD, 0)
        i1 = impact.detect_index + REPLAY_TAIL
        last = impact.pre_index - 2
        first = max(i0 + TORQUE_SETTLE, last - TORQUE_WINDOW)
        if last - first < 3 or i1 > len(log):
            skipped.append({"id": entry.id, "reason": "too short around the impact for a replay"})
            continue
        if i1 < len(log):
            # impulse and contact duration over the span that the replay covers
            impact = measure_impact(log.truncated(log.t[i1]))
        tangential = entry.reference_tangential_velocity
        trials.append(
            MeasuredTrial(
                id=entry.id,
                posture=entry.posture,
                reference_speed=entry.reference_normal_speed,
                tangential_speed=float(np.linalg.norm(tangential)) if tangential is not None else 0.0,
                q0=log.q[i0].copy(),
                dq0=log.dq[max(i0 - START_AVERAGE, 0) : i0 + START_AVERAGE + 1].mean(axis=0),
                servo_reference=servo_reference_from_commands(
                    log.q[0], log.dq[: START_AVERAGE + 1].mean(axis=0), log.dq_cmd[:i0], period
                ),
                dq_cmd=log.dq_cmd[i0:i1].copy(),
                control_period=period,
                jump=impact.dq_jump,
                impulse=impact.impulse,
                duration=impact.duration,
                torque=log.tau[first:last].mean(axis=0),
                q_pre=impact.q_pre,
                dq_pre=impact.dq_pre,
                torque_window=(first - i0, last - i0),
            )
        )
    return trials, skipped, dataset.header.surface


def replay(scene, trial: MeasuredTrial) -> ReplayFeatures:
    """Replay one trial in ``scene`` and measure it like the real one.

    A replay that finds no impact, or that MuJoCo flags as unstable (bad accelerations, e.g. a
    servo gain beyond what the 1 kHz loop can hold), is marked failed: its jump and impulse are
    zero, so the fit's residuals push away from it.
    """
    try:
        log = run_trial(
            scene,
            CommandReplay(trial.dq_cmd),
            trial.q0,
            trial.dq0,
            len(trial.dq_cmd) * trial.control_period,
            control_period=trial.control_period,
            servo_reference=trial.servo_reference,
        )
    except SimulationUnstableError:
        return ReplayFeatures(np.zeros(NQ), np.zeros(3), 0.0, np.zeros(NQ))
    first, last = trial.torque_window
    torque = log.tau[first:last].mean(axis=0)
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError:
        return ReplayFeatures(np.zeros(7), np.zeros(3), 0.0, torque)
    return ReplayFeatures(impact.dq_jump, impact.impulse, impact.duration, torque)


def replay_all(surface: Surface, plant: PlantParameters, trials: list[MeasuredTrial]) -> list[ReplayFeatures]:
    scene = build_scene(surface, plant)
    return [replay(scene, trial) for trial in trials]


def residuals(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    parts = []
    for f, trial in zip(features, trials):
        parts.append((f.jump - trial.jump) / SIGMA_JUMP)
        parts.append((f.torque - trial.torque) / SIGMA_TORQUE)
        if trial.impulse is not None and f.impulse is not None:
            parts.append((f.impulse - trial.impulse) / SIGMA_IMPULSE)
            parts.append([(f.duration - trial.duration) / SIGMA_DURATION])
    return np.concatenate(parts)


def jump_errors(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    """Average error (26) of each replayed jump against the measured one."""
    return np.array([average_prediction_error(f.jump, t.jump) for f, t in zip(features, trials)])


# ---------------------------------------------------------------------------- fitting
def cause_grid(cause: Cause, nominal: PlantParameters) -> list[np.ndarray]:
    """The nominal value and a regular grid over the bounds (in the fitted space u)."""
    lo, hi = cause.u_bounds()
    n = GRID_POINTS[len(lo)]
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lo))
    return [cause.to_u(cause.nominal_theta(nominal))] + [np.array(p) for p in grid]


def evaluate_grid(cause: Cause, nominal: PlantParameters, surface: Surface, trials):
    """Replay features of every trial at every grid point of the cause."""
    points = cause_grid(cause, nominal)
    return points, [replay_all(surface, cause.plant(nominal, u), trials) for u in points]


def fit_cause(cause: Cause, nominal, surface, trials, start: np.ndarray, max_evaluations: int) -> np.ndarray:
    """Least squares over the replays of ``trials``: minimise the sum of squared residuals from
    ``start`` within the bounds, with Powell's derivative-free method (the replayed features are
    only piecewise smooth in the parameters: the jump is read at a sample index that can switch,
    which defeats finite-difference Jacobians). Returns the best u evaluated."""
    lo, hi = cause.u_bounds()
    best = {"cost": np.inf, "u": np.clip(start, lo, hi)}

    def cost(u):
        value = float(np.sum(residuals(replay_all(surface, cause.plant(nominal, u), trials), trials) ** 2))
        if value < best["cost"]:
            best.update(cost=value, u=np.array(u))
        return value

    minimize(
        cost,
        best["u"],
        method="Powell",
        bounds=list(zip(lo, hi)),
        options={
            "xtol": FIT_XTOL,
            "ftol": 1e-6,
            "maxfev": max_evaluations * len(lo),
            "direc": np.diag((hi - lo) / GRID_POINTS[len(lo)]),
        },
    )
    return best["u"]


def fold_of(trials: list[MeasuredTrial]) -> np.ndarray:
    k = min(MAX_FOLDS, len(trials))
    return np.arange(len(trials)) % k


def cross_validate_cause(args) -> dict:
    """Held-out errors of one cause (one process task): grid once, then a fit per fold + all."""
    cause, nominal, surface, trials = args
    points, grid = evaluate_grid(cause, nominal, surface, trials)
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    for k in np.unique(folds):
        train = [t for t, f in zip(trials, folds) if f != k]
        test = [t for t, f in zip(trials, folds) if f == k]
        train_idx = [i for i, f in enumerate(folds) if f != k]
        costs = [np.sum(residuals([g[i] for i in train_idx], train) ** 2) for g in grid]
        u = fit_cause(cause, nominal, surface, train, points[int(np.argmin(costs))], FOLD_MAX_EVALUATIONS)
        heldout[folds == k] = jump_errors(replay_all(surface, cause.plant(nominal, u), test), test)
    costs = [np.sum(residuals(g, trials) ** 2) for g in grid]
    u_all = fit_cause(cause, nominal, surface, trials, points[int(np.argmin(costs))], FIT_MAX_EVALUATIONS)
    return {"cause": cause.name, "u": u_all, "heldout": heldout}


# ---------------------------------------------------------------------------- predictors
def predictor_errors(trials: list[MeasuredTrial], surface: Surface) -> tuple[dict, dict, dict]:
    """Average error (26) of each predictor at the logged pre-impact states (v- = J dq-,
    c_r = 0): with its own impulse, and fed the measured impulse where a force log exists.
    Also returns the predicted jumps (trials x 7) per method."""
    robot = PandaModel()
    own = {m: [] for m in METHODS}
    fed = {m: [] for m in METHODS}
    predictions = {m: [] for m in METHODS}
    for trial in trials:
        terms = robot.terms(trial.q_pre, trial.dq_pre, check_limits=False)
        v_minus = terms.J @ trial.dq_pre
        for m in METHODS:
            jump = JUMP_MODELS[m].predict(terms, surface.normal, v_minus, 0.0).dq_jump
            predictions[m].append(jump)
            own[m].append(average_prediction_error(jump, trial.jump))
            if trial.impulse is not None:
                measured = JUMP_MODELS[m].predict(terms, surface.normal, v_minus, 0.0, impulse=trial.impulse)
                fed[m].append(average_prediction_error(measured.dq_jump, trial.jump))
    return (
        {m: float(np.mean(own[m])) for m in METHODS},
        {m: float(np.mean(fed[m])) for m in METHODS if fed[m]},
        {m: np.array(p) for m, p in predictions.items()},
    )


# ---------------------------------------------------------------------------- report
@dataclass
class Diagnosis:
    trials: list[MeasuredTrial]
    skipped: list[dict]
    nominal_jumps: np.ndarray
    extended_jumps: np.ndarray
    baseline_errors: np.ndarray
    candidates: list[dict]
    cause: str
    explained: bool
    parameters: dict
    predictors: dict
    predictors_measured_impulse: dict
    predictions: dict
    analysis: dict

    def summary(self) -> dict:
        best = next(c for c in self.candidates if c["cause"] == self.cause)
        baseline = float(np.mean(self.baseline_errors))
        return {
            "cause": self.cause,
            "explained": self.explained,
            "parameters": self.parameters,
            "baseline_error": baseline,
            "extended_error": best["heldout_error"],
            "gain": best["gain"],
            "candidates": self.candidates,
            "trials": len(self.trials),
            "skipped": self.skipped,
            "predictors": self.predictors,
            "predictors_measured_impulse": self.predictors_measured_impulse,
            "analysis": self.analysis,
            "message": self.message(),
        }

    def message(self) -> str:
        best = next(c for c in self.candidates if c["cause"] == self.cause)
        if self.explained:
            return (
                f"The simulation's jump error is explained by '{self.cause}': fitting it lowers the "
                f"held-out average error from {np.mean(self.baseline_errors):.4f} to "
                f"{best['heldout_error']:.4f} rad/s ({100 * best['gain']:.0f} % gain)."
            )
        return (
            f"No candidate cause explains the gap: the best one, '{self.cause}', lowers the held-out "
            f"average error by only {100 * best['gain']:.0f} % (threshold {100 * EXPLAINED_GAIN:.0f} %); "
            "the nominal simulation is as good as the candidates allow."
        )


def error_analysis(trials: list[MeasuredTrial], nominal_jumps: np.ndarray) -> dict:
    measured = np.array([t.jump for t in trials])
    errors = nominal_jumps - measured  # eq. (25)
    speeds = np.array([t.reference_speed for t in trials])
    avg = np.mean(np.abs(errors), axis=1)  # eq. (26)
    ratio = np.sum(nominal_jumps * measured, axis=0) / np.maximum(np.sum(measured**2, axis=0), 1e-12)
    share = np.sum(np.abs(errors), axis=0) / max(np.sum(np.abs(errors)), 1e-12)
    slope = float(np.polyfit(speeds, avg, 1)[0]) if np.ptp(speeds) > 0 else 0.0
    groups: dict[str, dict[str, list[float]]] = {}
    for t, e in zip(trials, avg):
        key = f"{t.reference_speed:.3f}" + (f"+t{t.tangential_speed:.3f}" if t.tangential_speed else "")
        groups.setdefault(t.posture or "unknown", {}).setdefault(key, []).append(float(e))
    return {
        "per_joint_mean_error": np.mean(errors, axis=0).tolist(),
        "per_joint_mean_abs_error": np.mean(np.abs(errors), axis=0).tolist(),
        "per_joint_sim_to_measured_ratio": ratio.tolist(),
        "per_joint_error_share": share.tolist(),
        "error_vs_speed_slope": slope,
        "per_posture_speed": {p: {k: float(np.mean(v)) for k, v in d.items()} for p, d in groups.items()},
    }


def diagnose(
    directory: str | Path,
    *,
    nominal: PlantParameters | None = None,
    causes: list[Cause] | None = None,
    jobs: int = 1,
) -> Diagnosis:
    nominal = nominal or PlantParameters()
    trials, skipped, surface = load_trials(directory)
    if len(trials) < 2:
        raise BadInputError(
            f"{directory}: only {len(trials)} usable trial(s); the diagnosis needs at least 2 "
            f"(skipped: {skipped})"
        )
    causes = causes if causes is not None else default_causes(surface.friction)
    nominal_features = replay_all(surface, nominal, trials)
    nominal_jumps = np.array([f.jump for f in nominal_features])
    baseline_errors = jump_errors(nominal_features, trials)
    baseline = float(np.mean(baseline_errors))
    tasks = [(cause, nominal, surface, trials) for cause in causes]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = list(pool.map(cross_validate_cause, tasks))
    else:
        results = [cross_validate_cause(t) for t in tasks]
    candidates = []
    for cause, result in zip(causes, results):
        heldout = float(np.mean(result["heldout"]))
        candidates.append(
            {
                "cause": cause.name,
                "parameters": cause.overrides(cause.to_theta(result["u"])),
                "heldout_error": heldout,
                "gain": 1.0 - heldout / baseline if baseline > 0 else 0.0,
            }
        )
    best_index = int(np.argmax([c["gain"] for c in candidates]))
    best = candidates[best_index]
    extended_plant = causes[best_index].plant(nominal, results[best_index]["u"])
    extended_jumps = np.array([f.jump for f in replay_all(surface, extended_plant, trials)])
    predictors, predictors_measured_impulse, predictions = predictor_errors(trials, surface)
    return Diagnosis(
        trials=trials,
        skipped=skipped,
        nominal_jumps=nominal_jumps,
        extended_jumps=extended_jumps,
        baseline_errors=baseline_errors,
        candidates=candidates,
        cause=best["cause"],
        explained=best["gain"] >= EXPLAINED_GAIN,
        parameters=best["parameters"],
        predictors=predictors,
        predictors_measured_impulse=predictors_measured_impulse,
        predictions=predictions,
        analysis=error_analysis(trials, nominal_jumps),
    )
