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
4. **Extend.** Candidate causes (``sim.causes``) are fitted by bounded least squares over the
   replays (sum of squared residuals minimised by ``scipy.optimize.minimize``, Powell, from the
   best point of each cause's grid). The residuals per trial are the jump error (7) /
   SIGMA_JUMP, the error of the mean joint torque over the ``TORQUE_WINDOW`` samples before
   contact (7) / SIGMA_TORQUE, and, with force data, the impulse error (3) / SIGMA_IMPULSE and
   the contact duration error / SIGMA_DURATION.
5. **Select the causes** (``select_causes``): forward selection on the held-out average error
   (26) of K-fold cross-validation over trials (K = min(3, trials)). Each step adds the
   candidate that lowers the held-out error most and must gain ``STEP_GAIN`` over the causes
   before it; the chosen causes are refitted jointly after each step; first steps within
   ``BRANCH_MARGIN`` of the best each start a path, and the path with the lowest held-out error
   is kept. The causes explain the gap when together they gain ``EXPLAINED_GAIN`` over the
   nominal replay (else ``explained`` is false). Jumps are compared at fixed samples per trial
   (``locate_jump_samples``).
6. **Bound the parameters** (``parameter_intervals``): Gauss-Newton polish of the joint fit, then
   per parameter the union of a profile-likelihood interval and a one-step bootstrap over
   trials; a side where the profile reaches the fit's bound inside the 95 % region is open
   (None), and the causes say which trials would settle it. Method: ``docs/diagnosis.md``.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.stats import t as student_t

from impactqp.controller.model.jump import JUMP_MODELS, METHODS, average_prediction_error
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import NQ, PandaModel

from .causes import Cause, default_causes
from impactqp.controller.measured.dataset import read_dataset, validate
from impactqp.controller.measured.impact import (
    POST_HALF_WIDTH,
    PRE_SAMPLES,
    ImpactNotFoundError,
    measure_impact,
)
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
EXPLAINED_GAIN = 0.30  # the first cause must lower the held-out error (26) by 30 % of the nominal's
STEP_GAIN = 0.20  # every further cause by 20 % of the held-out error of the causes before it
MAX_CAUSES = 3
BRANCH_MARGIN = 0.10  # first-step candidates within 10 % of the best held-out error start their own path
MAX_BRANCHES = 3
MAX_FOLDS = 3
FIT_XTOL = 2e-3
POWELL_STEPS = 6  # Powell's first step along each parameter: its range / 6
FIT_MAX_EVALUATIONS = 20  # per fitted parameter, for the fit on all trials
FOLD_MAX_EVALUATIONS = 10  # per fitted parameter, for each cross-validation fold
JOINT_MAX_EVALUATIONS = 15  # per fitted parameter, for the joint refit of the chosen causes
CHI2_95 = 3.841  # 95 % quantile of chi^2 with 1 degree of freedom
SCAN_FIRST_STEP = 1.0 / 40.0
JACOBIAN_STEP = 0.01
POLISH_ITERATIONS = 3
BOOTSTRAP_SAMPLES = 1000
BOOTSTRAP_SEED = 0
SCAN_BISECTIONS = 2


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
    dq_log: np.ndarray  # the measured dq over the replay's span (replay sample k is dq_log[k])
    jump_samples: tuple[int, int]  # replay samples (pre, post) where the fit reads the jumps

    @property
    def reference(self) -> np.ndarray:
        """The measured jump read at ``jump_samples`` (``jump_at``): what the fit compares."""
        return jump_at(self.dq_log, *self.jump_samples)


def jump_at(dq: np.ndarray, pre: int, post: int) -> np.ndarray:
    """The jump of the velocities ``dq`` read at the samples (pre, post) with the averages of
    ``controller.measured.impact``: the mean of 2 h + 1 samples about ``post`` minus the mean of
    the ``PRE_SAMPLES`` ending at ``pre``."""
    dq_pre = dq[pre - PRE_SAMPLES + 1 : pre + 1].mean(axis=0)
    return dq[post - POST_HALF_WIDTH : post + POST_HALF_WIDTH + 1].mean(axis=0) - dq_pre


@dataclass(frozen=True)
class ReplayFeatures:
    """What a replay gives: its jump read at the trial's ``jump_samples`` (compared with the
    trial's ``reference``), its impulse, contact duration and pre-impact torque, and its jump
    as ``controller.measured.impact`` detects and reads it (for the report)."""

    jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None
    torque: np.ndarray
    detected_jump: np.ndarray


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
                dq_log=log.dq[i0:i1].copy(),
                jump_samples=(impact.pre_index - i0, impact.post_index - i0),
            )
        )
    return trials, skipped, dataset.header.surface


def replay_log(scene, trial: MeasuredTrial):
    """The simulated log of ``trial`` replayed in ``scene``: from its start state, the servo
    reference rebuilt from its commands, driven by its logged commands."""
    return run_trial(
        scene,
        CommandReplay(trial.dq_cmd),
        trial.q0,
        trial.dq0,
        len(trial.dq_cmd) * trial.control_period,
        control_period=trial.control_period,
        servo_reference=trial.servo_reference,
    )


def replay(scene, trial: MeasuredTrial) -> ReplayFeatures:
    """Replay one trial in ``scene`` and measure it like the real one: its jump at the trial's
    ``jump_samples``, its impulse and duration from its contact force.

    A replay that MuJoCo flags as unstable (bad accelerations, e.g. a servo gain beyond what the
    1 kHz loop can hold) is marked failed: its jump and impulse are zero, so the fit's residuals
    push away from it; so are the impulse and the detected jump of a replay without an impact.
    """
    try:
        log = replay_log(scene, trial)
    except SimulationUnstableError:
        return ReplayFeatures(np.zeros(NQ), np.zeros(3), 0.0, np.zeros(NQ), np.zeros(NQ))
    first, last = trial.torque_window
    torque = log.tau[first:last].mean(axis=0)
    jump = jump_at(log.dq, *trial.jump_samples)
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError:
        return ReplayFeatures(jump, np.zeros(3), 0.0, torque, np.zeros(NQ))
    return ReplayFeatures(jump, impact.impulse, impact.duration, torque, impact.dq_jump)


def locate_jump_samples(trials: list[MeasuredTrial], surface: Surface, plant: PlantParameters) -> list[MeasuredTrial]:
    """The trials with the post-impact sample of their ``jump_samples`` taken from their replay
    in ``plant`` (the nominal one) instead of the measured velocities.

    ``controller.measured.impact`` reads the jump at the sample of largest change, which encoder
    noise biases towards larger jumps when the velocities are noisy (a positive noise sample is
    likelier to be the largest). The replay is noise-free, so its sample is chosen without the
    measured noise, the measured jump read there is unbiased, and the fit reads every replay at
    the same fixed samples: no cause can move the sample the data are read at, and the read
    jump is smooth in the parameters (``docs/diagnosis.md``). A trial whose replay finds no
    impact keeps its measured samples."""
    scene = build_scene(surface, plant)
    located = []
    for trial in trials:
        try:
            post = measure_impact(replay_log(scene, trial)).post_index
        except (SimulationUnstableError, ImpactNotFoundError):
            located.append(trial)
            continue
        pre = trial.jump_samples[0]
        located.append(replace(trial, jump_samples=(pre, max(post, pre + 1))))
    return located


def replay_all(surface: Surface, plant: PlantParameters, trials: list[MeasuredTrial]) -> list[ReplayFeatures]:
    scene = build_scene(surface, plant)
    return [replay(scene, trial) for trial in trials]


def residuals(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    parts = []
    for f, trial in zip(features, trials):
        parts.append((f.jump - trial.reference) / SIGMA_JUMP)
        parts.append((f.torque - trial.torque) / SIGMA_TORQUE)
        if trial.impulse is not None:  # a replay without a force contact counts as a zero impulse
            impulse, duration = (np.zeros(3), 0.0) if f.impulse is None else (f.impulse, f.duration)
            parts.append((impulse - trial.impulse) / SIGMA_IMPULSE)
            parts.append([(duration - trial.duration) / SIGMA_DURATION])
    return np.concatenate(parts)


def residual_sizes(trials: list[MeasuredTrial]) -> list[int]:
    """How many residuals each trial contributes (``residuals``)."""
    return [14 + (4 if t.impulse is not None else 0) for t in trials]


def jump_errors(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    """Average error (26) of each replayed jump against the measured one, both read at the
    trial's ``jump_samples``."""
    return np.array([average_prediction_error(f.jump, t.reference) for f, t in zip(features, trials)])


# ---------------------------------------------------------------------------- fitting
@dataclass(frozen=True)
class FittedCauses:
    """Causes with their fitted vectors u, applied in order on top of a plant."""

    causes: tuple[Cause, ...] = ()
    u: tuple[np.ndarray, ...] = ()

    def plant(self, nominal: PlantParameters) -> PlantParameters:
        for cause, u in zip(self.causes, self.u):
            nominal = cause.plant(nominal, u)
        return nominal

    def plus(self, cause: Cause, u: np.ndarray) -> "FittedCauses":
        return FittedCauses(self.causes + (cause,), self.u + (np.asarray(u, float),))

    def with_vector(self, u_all: np.ndarray) -> "FittedCauses":
        """The same causes with the concatenated vector ``u_all`` split back per cause."""
        sizes = np.cumsum([len(u) for u in self.u])[:-1]
        return FittedCauses(self.causes, tuple(np.split(np.asarray(u_all, float), sizes)))

    def vector(self) -> np.ndarray:
        return np.concatenate(self.u) if self.u else np.zeros(0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = zip(*(c.u_bounds() for c in self.causes))
        return np.concatenate(lo), np.concatenate(hi)

    def overrides(self) -> dict:
        merged: dict = {}
        for cause, u in zip(self.causes, self.u):
            merged.update(cause.overrides(cause.to_theta(u)))
        return merged


def cost_of(plant: PlantParameters, surface: Surface, trials) -> float:
    return float(np.sum(residuals(replay_all(surface, plant, trials), trials) ** 2))


def fit(model: FittedCauses, base: PlantParameters, surface, trials, max_evaluations: int) -> FittedCauses:
    """Least squares over the replays of ``trials``: minimise the sum of squared residuals over
    the vectors of ``model`` (its current vectors are the start), with the plant ``base`` under
    them, within the bounds, with Powell's derivative-free method (the replayed features are
    only piecewise smooth in the parameters: the contact duration and impulse end at a force
    sample that can switch, which defeats finite-difference Jacobians). Returns the best point
    evaluated."""
    lo, hi = model.bounds()
    best = {"cost": np.inf, "u": np.clip(model.vector(), lo, hi)}

    def cost(u):
        value = cost_of(model.with_vector(u).plant(base), surface, trials)
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
            "direc": np.diag((hi - lo) / POWELL_STEPS),
        },
    )
    return model.with_vector(best["u"])


def fold_of(trials: list[MeasuredTrial]) -> np.ndarray:
    k = min(MAX_FOLDS, len(trials))
    return np.arange(len(trials)) % k


def best_start(cause: Cause, base: PlantParameters, surface, trials, features_of_grid=None):
    """The grid point of ``cause`` (on top of ``base``) with the least cost over ``trials``:
    (its index, the grid, the replay features at every grid point)."""
    points = cause.grid(base)
    if features_of_grid is None:
        features_of_grid = [replay_all(surface, cause.plant(base, u), trials) for u in points]
    costs = [np.sum(residuals(f, trials) ** 2) for f in features_of_grid]
    return int(np.argmin(costs)), points, features_of_grid


def cross_validate_cause(args) -> dict:
    """Held-out errors of one candidate added to the causes already chosen (one process task).

    ``bases[k]`` is the plant of the chosen causes fitted without fold k, ``base_all`` the one
    fitted on all trials. Per fold: the best grid point on the training trials starts a fit of
    the candidate on them, and its replay of the held-out trials gives their errors (26). Then
    the candidate is fitted on all trials on top of ``base_all``."""
    cause, bases, base_all, surface, trials = args
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    u_folds = []
    shared = None  # grid features on all trials, when every fold shares the base (first step)
    if all(b == base_all for b in bases):
        _, _, shared = best_start(cause, base_all, surface, trials)
    for k in np.unique(folds):
        train_idx = [i for i, f in enumerate(folds) if f != k]
        train = [trials[i] for i in train_idx]
        test = [t for t, f in zip(trials, folds) if f == k]
        grid = [[g[i] for i in train_idx] for g in shared] if shared is not None else None
        i, points, _ = best_start(cause, bases[k], surface, train, grid)
        fitted = fit(FittedCauses((cause,), (points[i],)), bases[k], surface, train, FOLD_MAX_EVALUATIONS)
        u_folds.append(fitted.u[0])
        heldout[folds == k] = jump_errors(replay_all(surface, fitted.plant(bases[k]), test), test)
    i, points, _ = best_start(cause, base_all, surface, trials, shared)
    u_all = fit(FittedCauses((cause,), (points[i],)), base_all, surface, trials, FIT_MAX_EVALUATIONS).u[0]
    return {"cause": cause.name, "u": u_all, "u_folds": u_folds, "heldout": heldout}


def screen_cause(args) -> float:
    """In-sample average error (26) of the best grid point of a candidate added on top of
    ``base`` (a cheap screen before its cross-validation)."""
    cause, base, surface, trials = args
    index, _, features = best_start(cause, base, surface, trials)
    return float(np.mean(jump_errors(features[index], trials)))


def run_tasks(function, tasks: list, jobs: int) -> list:
    if jobs > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(min(jobs, len(tasks))) as pool:
            return list(pool.map(function, tasks))
    return [function(t) for t in tasks]


@dataclass
class Selection:
    """The result of the forward selection (``select_causes``)."""

    candidates: list[dict]  # the first step: every candidate alone
    steps: list[dict]  # one entry per step: the best candidate, its held-out error and gain
    model: FittedCauses  # the selected causes, refitted jointly on all trials
    best: FittedCauses  # the best first-step candidate alone (the report when nothing explains)
    heldout_errors: np.ndarray  # per trial, of the last selected step (or of the best candidate)


@dataclass
class Branch:
    """One path of the forward selection: the chosen causes fitted jointly on all trials
    (``model``), fitted without each fold (``bases``), the steps taken and the held-out errors
    per trial of the last one (of the nominal replay before any step)."""

    model: FittedCauses
    bases: list[PlantParameters]
    steps: list[dict]
    heldout: np.ndarray

    @property
    def error(self) -> float:
        return float(np.mean(self.heldout))


def relative_gain(error: float, reference: float) -> float:
    """1 - error / reference: the share of the ``reference`` error removed (0 without one)."""
    return 1.0 - error / reference if reference > 0 else 0.0


def selection_step(cause: Cause, heldout_error: float, previous_error: float) -> dict:
    """One entry of ``steps``: the cause, its held-out error, its gain over the error before it,
    and whether that gain reaches ``STEP_GAIN``."""
    gain = relative_gain(heldout_error, previous_error)
    return {"cause": cause.name, "heldout_error": heldout_error, "gain": gain, "selected": gain >= STEP_GAIN}


def take_step(branch: Branch, step: dict, cause: Cause, result: dict, nominal, surface, trials) -> Branch:
    """``branch`` after the accepted ``step``: ``cause`` added (its cross-validation
    ``result``) and the chosen causes refitted jointly."""
    model = branch.model.plus(cause, result["u"])
    if len(model.causes) > 1:
        model = fit(model, nominal, surface, trials, JOINT_MAX_EVALUATIONS)
    bases = [cause.plant(b, u) for b, u in zip(branch.bases, result["u_folds"])]
    return Branch(model, bases, branch.steps + [step], result["heldout"])


def cross_validate_step(branch: Branch, causes: list[Cause], nominal, surface, trials, jobs: int):
    """The remaining candidates of ``branch`` worth cross-validating, and their results.

    From the second step on, a candidate whose best grid point does not lower the in-sample
    error (26) by ``STEP_GAIN / 2`` is left out (its held-out gain could not reach
    ``STEP_GAIN``)."""
    chosen = {c.name for c in branch.model.causes}
    pool = [c for c in causes if c.name not in chosen]
    base_all = branch.model.plant(nominal)
    if branch.model.causes and pool:
        current = float(np.mean(jump_errors(replay_all(surface, base_all, trials), trials)))
        screened = run_tasks(screen_cause, [(c, base_all, surface, trials) for c in pool], jobs)
        pool = [c for c, e in zip(pool, screened) if e <= (1.0 - STEP_GAIN / 2) * current]
    results = run_tasks(cross_validate_cause, [(c, branch.bases, base_all, surface, trials) for c in pool], jobs)
    return pool, results


def forward(branch: Branch, causes: list[Cause], nominal, surface, trials, jobs: int) -> Branch:
    """Greedy forward steps from ``branch`` until a step gains less than ``STEP_GAIN`` or
    ``MAX_CAUSES`` are chosen; the rejected last step is recorded (``selected`` false)."""
    while len(branch.model.causes) < MAX_CAUSES:
        pool, results = cross_validate_step(branch, causes, nominal, surface, trials, jobs)
        if not pool:
            break
        errors = [float(np.mean(r["heldout"])) for r in results]
        i = int(np.argmin(errors))
        step = selection_step(pool[i], errors[i], branch.error)
        if not step["selected"]:
            branch.steps = branch.steps + [step]
            break
        branch = take_step(branch, step, pool[i], results[i], nominal, surface, trials)
    return branch


def select_causes(
    causes: list[Cause], nominal: PlantParameters, surface: Surface, trials, baseline_errors, jobs: int
) -> Selection:
    """Forward selection on held-out error (``docs/diagnosis.md``).

    Step s cross-validates every remaining candidate added to the s - 1 causes chosen so far
    (each fold on top of the chosen causes fitted without that fold) and takes the one with the
    lowest held-out average error (26). Its gain is 1 - heldout_s / heldout_(s-1), heldout_0
    being the nominal simulation's; a step must gain ``STEP_GAIN``, else the selection stops
    (at most ``MAX_CAUSES`` causes). After each step the chosen causes are refitted jointly on
    all trials. The causes explain the gap when together they gain ``EXPLAINED_GAIN`` over the
    nominal simulation; otherwise none is selected.

    Two effects at once can leave their first steps close (each alone explains part of the
    gap, and a third cause can mimic a part of both): every first-step candidate whose held-out
    error is within ``BRANCH_MARGIN`` of the best one's starts its own path (at most
    ``MAX_BRANCHES``), and the path with the lowest final held-out error is kept.
    """
    folds = len(np.unique(fold_of(trials)))
    start = Branch(FittedCauses(), [nominal] * folds, [], np.asarray(baseline_errors, float))
    baseline = start.error
    pool, results = cross_validate_step(start, causes, nominal, surface, trials, jobs)
    errors = [float(np.mean(r["heldout"])) for r in results]
    candidates = [
        {
            "cause": c.name,
            "parameters": c.overrides(c.to_theta(r["u"])),
            "heldout_error": e,
            "gain": relative_gain(e, baseline),
        }
        for c, r, e in zip(pool, results, errors)
    ]
    order = np.argsort(errors, kind="stable")
    best = int(order[0])
    best_alone = FittedCauses((pool[best],), (results[best]["u"],))
    branches = []
    for i in order[:MAX_BRANCHES]:
        i = int(i)
        if i != best and errors[i] > (1.0 + BRANCH_MARGIN) * errors[best]:
            break
        step = selection_step(pool[i], errors[i], baseline)
        if not step["selected"]:
            branches.append(Branch(FittedCauses(), start.bases, [step], start.heldout))
            continue
        first = take_step(start, step, pool[i], results[i], nominal, surface, trials)
        branches.append(forward(first, causes, nominal, surface, trials, jobs))
    chosen = min(branches, key=lambda b: b.error)
    if chosen.model.causes and relative_gain(chosen.error, baseline) >= EXPLAINED_GAIN:
        return Selection(candidates, chosen.steps, chosen.model, best_alone, chosen.heldout)
    # the causes of the best path together do not explain the gap: none is selected
    steps = [{**step, "selected": False} for step in branches[0].steps]
    return Selection(candidates, steps, FittedCauses(), best_alone, results[best]["heldout"])


# ---------------------------------------------------------------------------- intervals
def residual_jacobian(model: FittedCauses, nominal, surface, trials) -> tuple[np.ndarray, np.ndarray]:
    """The residual vector at the fit and its Jacobian in u, by central differences of
    ``JACOBIAN_STEP`` of each parameter's range (one-sided at a bound)."""
    u0 = model.vector()
    lo, hi = model.bounds()

    def r(u):
        return residuals(replay_all(surface, model.with_vector(u).plant(nominal), trials), trials)

    r0 = r(u0)
    J = np.empty((len(r0), len(u0)))
    for j in range(len(u0)):
        h = JACOBIAN_STEP * (hi[j] - lo[j])
        up, down = u0.copy(), u0.copy()
        up[j], down[j] = min(u0[j] + h, hi[j]), max(u0[j] - h, lo[j])
        J[:, j] = (r(up) - r(down)) / (up[j] - down[j])
    return r0, J


def gauss_newton_polish(model: FittedCauses, nominal, surface, trials):
    """Up to ``POLISH_ITERATIONS`` Gauss-Newton steps from the derivative-free fit (each full,
    else half, kept only when it lowers the cost); returns the model, its residuals and their
    Jacobian (for the profile directions and the bootstrap)."""
    lo, hi = model.bounds()
    r0, J = residual_jacobian(model, nominal, surface, trials)
    for _ in range(POLISH_ITERATIONS):
        step = np.linalg.lstsq(J, -r0, rcond=None)[0]
        for fraction in (1.0, 0.5):
            u = np.clip(model.vector() + fraction * step, lo, hi)
            if cost_of(model.with_vector(u).plant(nominal), surface, trials) < float(r0 @ r0):
                model = model.with_vector(u)
                r0, J = residual_jacobian(model, nominal, surface, trials)
                break
        else:
            break
    return model, r0, J


def bootstrap_intervals(model: FittedCauses, r: np.ndarray, J: np.ndarray, sizes: list[int]) -> np.ndarray:
    """95 % intervals in u from a one-step bootstrap over trials: ``BOOTSTRAP_SAMPLES``
    resamples of the trials (with replacement), each refitted by the Gauss-Newton step from
    the fit, u_b = u* - pinv(J_b) r_b, with the residual blocks and Jacobian rows of the drawn
    trials. Returns (parameters, 2): the union of the percentile interval and
    u* +- t_0.975(n - p) sqrt(n / (n - 1)) sd(u_b), n trials and p parameters: with a dozen
    trials the bootstrap spread underestimates the sampling spread, and the Student quantile
    and the n / (n - 1) factor are the small-sample corrections of a trial-clustered standard
    error."""
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    edges = np.concatenate([[0], np.cumsum(sizes)])
    blocks = [np.arange(a, b) for a, b in zip(edges[:-1], edges[1:])]
    lo, hi = model.bounds()
    u0 = model.vector()
    samples = np.empty((BOOTSTRAP_SAMPLES, len(u0)))
    for b in range(BOOTSTRAP_SAMPLES):
        rows = np.concatenate([blocks[i] for i in rng.integers(0, len(blocks), len(blocks))])
        samples[b] = np.clip(u0 - np.linalg.lstsq(J[rows], r[rows], rcond=None)[0], lo, hi)
    n = len(blocks)
    half = student_t.ppf(0.975, max(n - len(u0), 1)) * np.sqrt(n / max(n - 1, 1)) * samples.std(axis=0)
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return np.stack([np.maximum(np.minimum(low, u0 - half), lo), np.minimum(np.maximum(high, u0 + half), hi)], axis=1)


def profile_direction(J: np.ndarray, index: int) -> np.ndarray:
    """Direction in u along which parameter ``index`` moves by 1 while the others follow the
    linearised profile: d_o = -pinv(J_o) J_i, the least-squares re-fit of the others."""
    others = [j for j in range(J.shape[1]) if j != index]
    d = np.zeros(J.shape[1])
    d[index] = 1.0
    if others:
        d[others] = -np.linalg.lstsq(J[:, others], J[:, index], rcond=None)[0]
    return d


def scan_side(args) -> float | None:
    """Where the cost leaves the 95 % region along one parameter's profile path, on one side
    (one process task).

    From the fitted u, the parameter moves in steps that double (``SCAN_FIRST_STEP`` of its
    range first) along ``direction`` (the others follow their linearised profile, clipped to
    their bounds) until the cost exceeds ``threshold`` above the fitted cost; the crossing is
    refined by ``SCAN_BISECTIONS`` bisections and a linear interpolation. Returns the theta of
    the crossing, or None when the parameter reaches its bound inside the region (open side)."""
    model, index, sign, direction, nominal, surface, trials, cost0, threshold = args
    u0 = model.vector()
    lo, hi = model.bounds()
    limit = hi[index] if sign > 0 else lo[index]

    def excess(x):
        u = np.clip(u0 + (x - u0[index]) * direction, lo, hi)
        return cost_of(model.with_vector(u).plant(nominal), surface, trials) - cost0

    inside, inside_excess = u0[index], 0.0
    step = SCAN_FIRST_STEP * (hi[index] - lo[index])
    while True:
        x = u0[index] + sign * step
        x = min(x, limit) if sign > 0 else max(x, limit)
        value = excess(x)
        if value >= threshold:
            outside, outside_excess = x, value
            break
        if x == limit:
            return None
        inside, inside_excess = x, max(value, 0.0)
        step *= 2.0
    for _ in range(SCAN_BISECTIONS):
        middle = 0.5 * (inside + outside)
        value = excess(middle)
        if value >= threshold:
            outside, outside_excess = middle, value
        else:
            inside, inside_excess = middle, max(value, 0.0)
    fraction = (threshold - inside_excess) / max(outside_excess - inside_excess, 1e-12)
    x = inside + fraction * (outside - inside)
    cause_index, local = parameter_owner(model, index)
    u = model.u[cause_index].copy()
    u[local] = x
    return float(model.causes[cause_index].to_theta(u)[local])


def parameter_owner(model: FittedCauses, index: int) -> tuple[int, int]:
    """(cause index, parameter index within the cause) of entry ``index`` of the vector."""
    for k, u in enumerate(model.u):
        if index < len(u):
            return k, index
        index -= len(u)
    raise IndexError(index)


def parameter_intervals(model: FittedCauses, nominal, surface, trials, jobs: int) -> tuple[FittedCauses, list[list]]:
    """The fit polished by Gauss-Newton, and 95 % intervals of every fitted parameter theta
    (per cause, per parameter, [low, high], None for an open side).

    Each interval is the union of two: the profile-likelihood interval (``scan_side``: with
    Gaussian residuals of unknown common scale s, the region cost - cost_min <= CHI2_95 s^2,
    s^2 = cost_min / (residuals - parameters)) and the percentile interval of a one-step
    bootstrap over trials (``bootstrap_intervals``), which also carries the trial-to-trial
    errors that the residual scale misses (e.g. of the replay's start state). A side is open
    when the profile scan reaches the bound of the fit still inside the region: the data do
    not bound the parameter there (``docs/diagnosis.md``)."""
    if not model.causes:
        return model, []
    model, r, J = gauss_newton_polish(model, nominal, surface, trials)
    cost0 = float(r @ r)
    threshold = CHI2_95 * cost0 / max(len(r) - len(model.vector()), 1)
    tasks = [
        (model, i, sign, profile_direction(J, i), nominal, surface, trials, cost0, threshold)
        for i in range(len(model.vector()))
        for sign in (-1.0, 1.0)
    ]
    ends = run_tasks(scan_side, tasks, jobs)
    boot = bootstrap_intervals(model, r, J, residual_sizes(trials))
    out, k = [], 0
    for cause, u in zip(model.causes, model.u):
        intervals = []
        for j in range(len(u)):
            low, high = ends[k + 2 * j], ends[k + 2 * j + 1]
            at = u.copy()
            at[j] = boot[k // 2 + j, 0]
            boot_low = float(cause.to_theta(at)[j])
            at[j] = boot[k // 2 + j, 1]
            boot_high = float(cause.to_theta(at)[j])
            intervals.append([
                None if low is None else min(low, boot_low),
                None if high is None else max(high, boot_high),
            ])
        out.append(intervals)
        k += 2 * len(u)
    return model, out


def override_intervals(model: FittedCauses, theta_intervals: list[list]) -> dict:
    """Intervals of the plant override keys: for each key, [low, high] (a list of them for a
    vector); each entry takes the interval of the fitted parameter that moves it (an entry no
    parameter moves gets [value, value]); None for an open side."""
    result: dict = {}
    for cause, u, intervals in zip(model.causes, model.u, theta_intervals):
        theta = cause.to_theta(u)
        base = cause.overrides(theta)
        entries = {k: [[v, v] for v in np.atleast_1d(value).tolist()] for k, value in base.items()}
        for j, (low, high) in enumerate(intervals):
            moved = theta.copy()
            moved[j] = theta[j] + max(1e-3 * abs(theta[j]), 1e-6)
            changed = cause.overrides(moved)
            for key, value in changed.items():
                for e, (old, new) in enumerate(zip(np.atleast_1d(base[key]), np.atleast_1d(value))):
                    if old != new:
                        ends = []
                        for end in (low, high):
                            if end is None:
                                ends.append(None)
                            else:
                                at = theta.copy()
                                at[j] = end
                                ends.append(float(np.atleast_1d(cause.overrides(at)[key])[e]))
                        entries[key][e] = ends
        for key, value in base.items():
            result[key] = entries[key] if isinstance(value, list) else entries[key][0]
    return result


def open_sides(model: FittedCauses, theta_intervals: list[list], trials: list[MeasuredTrial]) -> list[dict]:
    """Every parameter the data leave open on a side, with the trials that would settle it
    (in terms of the normal speeds of ``trials``)."""
    normal_speeds = np.array([t.reference_speed for t in trials])
    found = []
    for cause, u, intervals in zip(model.causes, model.u, theta_intervals):
        for j, (low, high) in enumerate(intervals):
            for side, end, other in (("below", low, high), ("above", high, low)):
                # what the data do tell: the closed end of the interval, else the fitted value
                known = float(cause.to_theta(u)[j]) if other is None else float(other)
                if end is None:
                    found.append(
                        {
                            "cause": cause.name,
                            "parameter": cause.labels[j],
                            "side": side,
                            "fitted": float(cause.to_theta(u)[j]),
                            "trials_needed": cause.settling_trials(j, side, known, normal_speeds),
                        }
                    )
    return found


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
    causes: list[str]
    steps: list[dict]
    intervals: dict
    parameter_intervals: list[dict]
    open_sides: list[dict]
    extended_error: float
    extended_plant: PlantParameters
    surface: Surface

    def summary(self) -> dict:
        baseline = float(np.mean(self.baseline_errors))
        return {
            "cause": self.cause,
            "causes": self.causes,
            "explained": self.explained,
            "parameters": self.parameters,
            "intervals": self.intervals,
            "parameter_intervals": self.parameter_intervals,
            "open_sides": self.open_sides,
            "steps": self.steps,
            "baseline_error": baseline,
            "extended_error": self.extended_error,
            "gain": relative_gain(self.extended_error, baseline),
            "candidates": self.candidates,
            "trials": len(self.trials),
            "skipped": self.skipped,
            "predictors": self.predictors,
            "predictors_measured_impulse": self.predictors_measured_impulse,
            "analysis": self.analysis,
            "message": self.message(),
        }

    def message(self) -> str:
        baseline = float(np.mean(self.baseline_errors))
        gain = relative_gain(self.extended_error, baseline)
        if self.explained:
            named = " + ".join(f"'{c}'" for c in self.causes)
            text = (
                f"The simulation's jump error is explained by {named}: fitting "
                f"{'it' if len(self.causes) == 1 else 'them'} lowers the held-out average error from "
                f"{baseline:.4f} to {self.extended_error:.4f} rad/s ({100 * gain:.0f} % gain)."
            )
        else:
            text = (
                f"No candidate cause explains the gap: the best one, '{self.cause}', lowers the held-out "
                f"average error by only {100 * gain:.0f} % (threshold {100 * EXPLAINED_GAIN:.0f} %); "
                "the nominal simulation is as good as the candidates allow."
            )
        if not self.explained:
            return text
        for p in self.parameter_intervals:
            text += f" {p['parameter']}: {p['value']:.4g}, 95 % interval {interval_text(p['interval'])}."
        for o in self.open_sides:
            text += (
                f" The data cannot bound {o['parameter']} {o['side']}: {o['trials_needed']}."
            )
        return text


def interval_text(interval) -> str:
    low, high = interval
    if low is None and high is None:
        return "unbounded both ways"
    if low is None:
        return f"at most {high:.4g} (open below)"
    if high is None:
        return f"at least {low:.4g} (open above)"
    return f"[{low:.4g}, {high:.4g}]"


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
    """Measure, replay, compare, select the causes, bound their parameters (module docstring)."""
    nominal = nominal or PlantParameters()
    trials, skipped, surface = load_trials(directory)
    if len(trials) < 2:
        raise BadInputError(
            f"{directory}: only {len(trials)} usable trial(s); the diagnosis needs at least 2 "
            f"(skipped: {skipped})"
        )
    causes = causes if causes is not None else default_causes(surface.friction)
    names = [c.name for c in causes]
    if len(set(names)) != len(names):
        raise ValueError(f"candidate causes must have distinct names, got {names}")
    trials = locate_jump_samples(trials, surface, nominal)
    nominal_features = replay_all(surface, nominal, trials)
    nominal_jumps = np.array([f.detected_jump for f in nominal_features])
    baseline_errors = jump_errors(nominal_features, trials)
    selection = select_causes(causes, nominal, surface, trials, baseline_errors, jobs)
    explained = bool(selection.model.causes)
    model = selection.model if explained else selection.best
    model, theta_intervals = parameter_intervals(model, nominal, surface, trials, jobs)
    extended_plant = model.plant(nominal)
    extended_jumps = np.array([f.detected_jump for f in replay_all(surface, extended_plant, trials)])
    predictors, predictors_measured_impulse, predictions = predictor_errors(trials, surface)
    per_parameter = [
        {"cause": c.name, "parameter": label, "value": float(value), "interval": interval}
        for c, u, intervals in zip(model.causes, model.u, theta_intervals)
        for label, value, interval in zip(c.labels, c.to_theta(u), intervals)
    ]
    return Diagnosis(
        trials=trials,
        skipped=skipped,
        nominal_jumps=nominal_jumps,
        extended_jumps=extended_jumps,
        baseline_errors=baseline_errors,
        candidates=selection.candidates,
        cause=model.causes[0].name,
        explained=explained,
        parameters=model.overrides(),
        predictors=predictors,
        predictors_measured_impulse=predictors_measured_impulse,
        predictions=predictions,
        analysis=error_analysis(trials, nominal_jumps),
        causes=[c.name for c in selection.model.causes],
        steps=selection.steps,
        intervals=override_intervals(model, theta_intervals),
        parameter_intervals=per_parameter,
        open_sides=open_sides(model, theta_intervals, trials),
        extended_error=float(np.mean(selection.heldout_errors)),
        extended_plant=extended_plant,
        surface=surface,
    )
