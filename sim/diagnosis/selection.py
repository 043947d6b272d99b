"""Which causes explain the gap: forward selection on held-out error (``select_causes``).

Forward selection on the held-out normalised residual (every block in noise units,
``fitting.trial_errors``; over trials, their quadratic mean) of K-fold cross-validation over
trials (K = min(``MAX_FOLDS``, trials)). Each step adds the candidate that lowers the held-out
error most and must gain ``STEP_GAIN`` over the causes before it; the chosen causes are refitted
jointly after each step; first steps within ``BRANCH_MARGIN`` of the best each start a path,
and the path with the lowest held-out error is kept. The causes are kept when together they
remove ``EXPLAINED_GAIN`` of the nominal replay's excess over the noise floor
(``gain_over_floor``; else none is selected); they explain the gap when their model also fits
the noise (``pipeline``). The rule and its reasons: ``docs/diagnosis.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import map_in_processes

from .fitting import FittedCauses, best_start, fit, jump_errors, trial_errors
from .noise import quadratic_mean
from .trials import MeasuredTrial, ReplaySetting, replay_all

EXPLAINED_GAIN = 0.20  # the causes must remove 20 % of the nominal's held-out excess over the noise floor
NOISE_FLOOR = 1.0  # the normalised residual of a model that fits: the noise itself
STEP_GAIN = 0.20  # every further cause by 20 % of the held-out error of the causes before it
MAX_CAUSES = 3
BRANCH_MARGIN = 0.10  # first-step candidates within 10 % of the best held-out error start their own path
MAX_BRANCHES = 3
MAX_FOLDS = 3
FIT_MAX_EVALUATIONS = 20  # per fitted parameter, for the fit on all trials
FOLD_MAX_EVALUATIONS = 10  # per fitted parameter, for each cross-validation fold
JOINT_MAX_EVALUATIONS = 15  # per fitted parameter, for the joint refit of the chosen causes


def fold_of(trials: list[MeasuredTrial]) -> np.ndarray:
    """The cross-validation fold of each trial: trial i is in fold i mod K, K = min(``MAX_FOLDS``, trials)."""
    k = min(MAX_FOLDS, len(trials))
    return np.arange(len(trials)) % k


@dataclass(frozen=True)
class CandidateTask:
    """One candidate to cross-validate on top of the causes already chosen (a process task):
    ``bases[k]`` is the plant of the chosen causes fitted without fold k, ``base_all`` the one
    fitted on all trials."""

    cause: Cause
    bases: tuple[PlantParameters, ...]
    base_all: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]


def cross_validate_cause(task: CandidateTask) -> dict:
    """Held-out errors of one candidate added to the causes already chosen (one process task).

    Per fold k: the best grid point on the training trials starts a fit of the candidate on
    them on top of ``bases[k]``, and its replay of the held-out trials gives their normalised
    residuals (``heldout``) and errors (26) (``heldout_jump``). Then the candidate is fitted on
    all trials on top of ``base_all``."""
    cause, setting, trials = task.cause, task.setting, list(task.trials)
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    heldout_jump = np.empty(len(trials))
    u_folds = []
    shared = None  # grid features on all trials, when every fold shares the base (first step)
    if all(b == task.base_all for b in task.bases):
        _, _, shared = best_start(cause, task.base_all, setting, trials)
    for k in np.unique(folds):
        train_idx = [i for i, f in enumerate(folds) if f != k]
        train = [trials[i] for i in train_idx]
        test = [t for t, f in zip(trials, folds) if f == k]
        grid = [[g[i] for i in train_idx] for g in shared] if shared is not None else None
        base = task.bases[k]
        i, points, _ = best_start(cause, base, setting, train, grid)
        fitted = fit(FittedCauses((cause,), (points[i],)), base, setting, train, FOLD_MAX_EVALUATIONS)
        u_folds.append(fitted.u[0])
        features = replay_all(setting, fitted.plant(base), test)
        heldout[folds == k] = trial_errors(features, test)
        heldout_jump[folds == k] = jump_errors(features, test)
    i, points, _ = best_start(cause, task.base_all, setting, trials, shared)
    u_all = fit(FittedCauses((cause,), (points[i],)), task.base_all, setting, trials, FIT_MAX_EVALUATIONS).u[0]
    return {"cause": cause.name, "u": u_all, "u_folds": u_folds, "heldout": heldout, "heldout_jump": heldout_jump}


@dataclass(frozen=True)
class ScreenTask:
    """One candidate to screen on top of the plant ``base`` of the causes chosen (a process task)."""

    cause: Cause
    base: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]


def screen_cause(task: ScreenTask) -> float:
    """In-sample normalised residual of the best grid point of a candidate added on top of
    ``base`` (a cheap screen before its cross-validation)."""
    trials = list(task.trials)
    index, _, features = best_start(task.cause, task.base, task.setting, trials)
    return quadratic_mean(trial_errors(features[index], trials))


@dataclass
class Selection:
    """The result of the forward selection (``select_causes``)."""

    candidates: list[dict]  # the first step: every candidate alone
    steps: list[dict]  # one entry per step: the best candidate, its held-out error and gain
    model: FittedCauses  # the selected causes, refitted jointly on all trials
    best: FittedCauses  # the best path's causes, else the best first-step candidate alone
    heldout_errors: np.ndarray  # normalised residual per trial, of ``model`` if it has causes, else of ``best``
    heldout_jump_errors: np.ndarray  # error (26) per trial, likewise
    gain_over_floor: float  # of the held-out errors above, against the nominal's


@dataclass
class Branch:
    """One path of the forward selection: the chosen causes fitted jointly on all trials
    (``model``), fitted without each fold (``bases``), the steps taken and the held-out
    normalised residuals and errors (26) per trial of the last one (of the nominal replay
    before any step)."""

    model: FittedCauses
    bases: list[PlantParameters]
    steps: list[dict]
    heldout: np.ndarray
    heldout_jump: np.ndarray

    @property
    def error(self) -> float:
        return quadratic_mean(self.heldout)


def relative_gain(error: float, reference: float) -> float:
    """1 - error / reference: the share of the ``reference`` error removed (0 without one)."""
    return 1.0 - error / reference if reference > 0 else 0.0


def gain_over_floor(error: float, reference: float) -> float:
    """(reference - error) / (reference - ``NOISE_FLOOR``): the share of the ``reference``
    error's excess over the noise floor removed (0 when the reference is at the floor)."""
    excess = reference - NOISE_FLOOR
    return (reference - error) / excess if excess > 0 else 0.0


def selection_step(cause: Cause, heldout_error: float, previous_error: float) -> dict:
    """One entry of ``steps``: the cause, its held-out error, its gain over the error before it,
    and whether that gain reaches ``STEP_GAIN``."""
    gain = relative_gain(heldout_error, previous_error)
    return {"cause": cause.name, "heldout_error": heldout_error, "gain": gain, "selected": gain >= STEP_GAIN}


def take_step(branch: Branch, step: dict, cause: Cause, result: dict, nominal, setting, trials) -> Branch:
    """``branch`` after the accepted ``step``: ``cause`` added (its cross-validation
    ``result``) and the chosen causes refitted jointly."""
    model = branch.model.plus(cause, result["u"])
    if len(model.causes) > 1:
        model = fit(model, nominal, setting, trials, JOINT_MAX_EVALUATIONS)
    bases = [cause.plant(b, u) for b, u in zip(branch.bases, result["u_folds"])]
    return Branch(model, bases, branch.steps + [step], result["heldout"], result["heldout_jump"])


def cross_validate_step(branch: Branch, causes: list[Cause], nominal, setting, trials, jobs: int):
    """The remaining candidates of ``branch`` worth cross-validating, and their results.

    From the second step on, a candidate whose best grid point does not lower the in-sample
    normalised residual by ``STEP_GAIN / 2`` is left out (its held-out gain could not reach
    ``STEP_GAIN``)."""
    chosen = {c.name for c in branch.model.causes}
    pool = [c for c in causes if c.name not in chosen]
    base_all = branch.model.plant(nominal)
    if branch.model.causes and pool:
        current = quadratic_mean(trial_errors(replay_all(setting, base_all, trials), trials))
        screens = [ScreenTask(c, base_all, setting, tuple(trials)) for c in pool]
        screened = map_in_processes(screen_cause, screens, jobs)
        pool = [c for c, e in zip(pool, screened) if e <= (1.0 - STEP_GAIN / 2) * current]
    tasks = [CandidateTask(c, tuple(branch.bases), base_all, setting, tuple(trials)) for c in pool]
    results = map_in_processes(cross_validate_cause, tasks, jobs)
    return pool, results


def forward(branch: Branch, causes: list[Cause], nominal, setting, trials, jobs: int) -> Branch:
    """Greedy forward steps from ``branch`` until a step gains less than ``STEP_GAIN`` or
    ``MAX_CAUSES`` are chosen; the rejected last step is recorded (``selected`` false)."""
    while len(branch.model.causes) < MAX_CAUSES:
        pool, results = cross_validate_step(branch, causes, nominal, setting, trials, jobs)
        if not pool:
            break
        errors = [quadratic_mean(r["heldout"]) for r in results]
        i = int(np.argmin(errors))
        step = selection_step(pool[i], errors[i], branch.error)
        if not step["selected"]:
            branch.steps = branch.steps + [step]
            break
        branch = take_step(branch, step, pool[i], results[i], nominal, setting, trials)
    return branch


def select_causes(
    causes: list[Cause], nominal: PlantParameters, setting: ReplaySetting, trials, baseline: tuple, jobs: int
) -> Selection:
    """Forward selection on held-out error (``docs/diagnosis.md``).

    ``baseline``: the nominal replays' normalised residual and error (26) per trial. Step s
    cross-validates every remaining candidate added to the s - 1 causes chosen so far (each
    fold on top of the chosen causes fitted without that fold) and takes the one with the
    lowest held-out normalised residual. Its gain is 1 - heldout_s / heldout_(s-1), heldout_0
    being the nominal simulation's; a step must gain ``STEP_GAIN``, else the selection stops
    (at most ``MAX_CAUSES`` causes). After each step the chosen causes are refitted jointly on
    all trials. The causes are kept when together they remove ``EXPLAINED_GAIN`` of the
    nominal simulation's excess over the noise floor (``gain_over_floor``); otherwise none is
    selected.

    Two effects at once can leave their first steps close (each alone explains part of the
    gap, and a third cause can mimic a part of both): every first-step candidate whose held-out
    error is within ``BRANCH_MARGIN`` of the best one's starts its own path (at most
    ``MAX_BRANCHES``), and the path with the lowest final held-out error is kept.
    """
    folds = len(np.unique(fold_of(trials)))
    start = Branch(FittedCauses(), [nominal] * folds, [], *(np.asarray(b, float) for b in baseline))
    baseline = start.error
    pool, results = cross_validate_step(start, causes, nominal, setting, trials, jobs)
    errors = [quadratic_mean(r["heldout"]) for r in results]
    candidates = [
        {
            "cause": c.name,
            "parameters": c.overrides(c.to_theta(r["u"])),
            "heldout_error": e,
            "gain": relative_gain(e, baseline),
            "gain_over_floor": gain_over_floor(e, baseline),
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
            branches.append(Branch(FittedCauses(), start.bases, [step], start.heldout, start.heldout_jump))
            continue
        first = take_step(start, step, pool[i], results[i], nominal, setting, trials)
        branches.append(forward(first, causes, nominal, setting, trials, jobs))
    chosen = min(branches, key=lambda b: b.error)
    floor_gain = gain_over_floor(chosen.error, baseline)
    if chosen.model.causes and floor_gain >= EXPLAINED_GAIN:
        return Selection(candidates, chosen.steps, chosen.model, chosen.model, chosen.heldout, chosen.heldout_jump, floor_gain)
    # the causes of the best path together do not remove enough of the excess: none is selected
    steps = [{**step, "selected": False} for step in chosen.steps]
    if chosen.model.causes:
        return Selection(candidates, steps, FittedCauses(), chosen.model, chosen.heldout, chosen.heldout_jump, floor_gain)
    heldout = results[best]["heldout"]
    return Selection(
        candidates, steps, FittedCauses(), best_alone, heldout, results[best]["heldout_jump"],
        gain_over_floor(quadratic_mean(heldout), baseline),
    )
