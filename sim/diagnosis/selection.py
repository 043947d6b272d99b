"""Cross-validation of causes on held-out error: the tasks the search (``search``) runs.

The held-out normalised residual (every block in noise units, ``fitting.trial_errors``; over
trials, their quadratic mean) of K-fold cross-validation over trials (K = min(``MAX_FOLDS``,
trials)):

- ``cross_validate_cause``: one candidate alone (the first step);
- ``screen_cause``: a cheap screen of a candidate next to the causes already chosen, a short
  local fit of all of them, in sample;
- ``cross_validate_model``: a set of causes refitted jointly without each fold, each fold from
  a start fitted without it (an addition, a removal or a refinement of the search).

A step gains ``STEP_GAIN`` over the error before it (``selection_step``); past the noise, the
gain must also be significant (``significant_gain``: a paired one-sided t-test over trials);
the causes must remove ``EXPLAINED_GAIN`` of the nominal's excess over the noise floor
(``gain_over_floor``). The rules
and their reasons: ``docs/diagnosis.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import t as student_t

from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters

from .fitting import FittedCauses, best_start, fit, jump_errors, trial_errors
from .intervals import gauss_newton_polish
from .noise import quadratic_mean
from .trials import MeasuredTrial, ReplaySetting, replay_all

EXPLAINED_GAIN = 0.20  # the causes must remove 20 % of the nominal's held-out excess over the noise floor
NOISE_FLOOR = 1.0  # the normalised residual of a model that fits: the noise itself
STEP_GAIN = 0.20  # every further cause by 20 % of the held-out error of the causes before it
SIGNIFICANCE = 0.99  # one-sided level of the paired test a further cause passes past the noise
MAX_FOLDS = 3
FIT_MAX_EVALUATIONS = 20  # per fitted parameter, for the fit on all trials
FOLD_MAX_EVALUATIONS = 10  # per fitted parameter, for each cross-validation fold
JOINT_MAX_EVALUATIONS = 15  # per fitted parameter, for the joint refit of the chosen causes
SCREEN_EVALUATIONS = 3  # per fitted parameter, for the short local fit of a screen
SCREEN_GRID_STRIDE = 2  # the screen starts its local fit from every other grid point (and the nominal)


def fold_of(trials: list[MeasuredTrial]) -> np.ndarray:
    """The cross-validation fold of each trial: trial i is in fold i mod K, K = min(``MAX_FOLDS``, trials)."""
    k = min(MAX_FOLDS, len(trials))
    return np.arange(len(trials)) % k


@dataclass(frozen=True)
class CandidateTask:
    """One candidate alone to cross-validate on top of the nominal plant ``base`` (a process
    task: the first step)."""

    cause: Cause
    base: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]


def cross_validate_cause(task: CandidateTask) -> dict:
    """Held-out errors of one candidate alone (one process task).

    Per fold k: the best grid point on the training trials starts a fit of the candidate on
    them, and its replay of the held-out trials gives their normalised residuals (``heldout``)
    and errors (26) (``heldout_jump``); ``u_folds`` are the fold fits. Then the candidate is
    fitted on all trials (``u``)."""
    cause, setting, trials, base = task.cause, task.setting, list(task.trials), task.base
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    heldout_jump = np.empty(len(trials))
    u_folds = []
    _, _, shared = best_start(cause, base, setting, trials)  # grid features on all trials, shared by the folds
    for k in np.unique(folds):
        train_idx = [i for i, f in enumerate(folds) if f != k]
        train = [trials[i] for i in train_idx]
        test = [t for t, f in zip(trials, folds) if f == k]
        i, points, _ = best_start(cause, base, setting, train, [[g[i] for i in train_idx] for g in shared])
        fitted = fit(FittedCauses((cause,), (points[i],)), base, setting, train, FOLD_MAX_EVALUATIONS)
        u_folds.append(fitted.u[0])
        features = replay_all(setting, fitted.plant(base), test)
        heldout[folds == k] = trial_errors(features, test)
        heldout_jump[folds == k] = jump_errors(features, test)
    i, points, _ = best_start(cause, base, setting, trials, shared)
    u_all = fit(FittedCauses((cause,), (points[i],)), base, setting, trials, FIT_MAX_EVALUATIONS).u[0]
    return {"cause": cause.name, "u": u_all, "u_folds": u_folds, "heldout": heldout, "heldout_jump": heldout_jump}


@dataclass(frozen=True)
class ScreenTask:
    """One candidate to screen next to the causes chosen, ``model`` on top of ``nominal`` (a
    process task)."""

    cause: Cause
    model: FittedCauses
    nominal: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]


def screen_cause(task: ScreenTask) -> tuple[float, FittedCauses]:
    """A cheap screen before a candidate's cross-validation: from its best point of a coarse
    grid (``SCREEN_GRID_STRIDE``) on top of the chosen causes, a short local fit
    (``SCREEN_EVALUATIONS`` per parameter of the fitter) of the candidate together with the
    chosen causes, which may move (one of them may have mimicked a part of the candidate's
    effect); the candidate's parameters come first, so Powell's first line searches move
    them. Returns the in-sample normalised residual of the screened model and the model (the
    candidate first)."""
    trials, setting = list(task.trials), task.setting
    base = task.model.plant(task.nominal)
    index, points, _ = best_start(task.cause, base, setting, trials, stride=SCREEN_GRID_STRIDE)
    start = FittedCauses((task.cause,) + task.model.causes, (points[index],) + task.model.u)
    model = fit(start, task.nominal, setting, trials, SCREEN_EVALUATIONS)
    return quadratic_mean(trial_errors(replay_all(setting, model.plant(task.nominal), trials), trials)), model


@dataclass(frozen=True)
class ModelTask:
    """A set of causes to cross-validate as a whole (a process task): ``model`` starts the fit on
    all trials, ``folds[k]`` the fit without fold k (fitted without it: no held-out trial
    leaks into a fold's start); ``added``, when given, is a candidate put first into every
    fold's start from its best coarse grid point on the fold's training trials (``model``
    holds it first already). ``newton``: every fit is a Gauss-Newton polish
    (``intervals.gauss_newton_polish``) instead of Powell's method: for a smooth, nearly linear
    cause with many parameters (the velocity scale per joint), which Powell's line searches,
    one parameter after the other, approach slowly."""

    model: FittedCauses
    folds: tuple[FittedCauses, ...]
    nominal: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]
    added: Cause | None = None
    newton: bool = False


def task_fit(task: ModelTask, start: FittedCauses, trials: list, max_evaluations: int) -> FittedCauses:
    """The fit of ``start`` over ``trials`` the way ``task`` asks (Powell, or Gauss-Newton)."""
    if task.newton:
        return gauss_newton_polish(start, task.nominal, task.setting, trials)[0]
    return fit(start, task.nominal, task.setting, trials, max_evaluations)


def cross_validate_model(task: ModelTask) -> dict:
    """The causes refitted jointly on all trials (``model``) and without each fold k from its
    start: the held-out normalised residuals and errors (26) of the fold's trials
    (``heldout``, ``heldout_jump``) and the fold fits (``folds``)."""
    setting, trials, nominal = task.setting, list(task.trials), task.nominal
    model = task_fit(task, task.model, trials, JOINT_MAX_EVALUATIONS)
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    heldout_jump = np.empty(len(trials))
    fold_models = []
    for k in np.unique(folds):
        train = [t for t, f in zip(trials, folds) if f != k]
        test = [t for t, f in zip(trials, folds) if f == k]
        start = task.folds[k]
        if task.added is not None:
            index, points, _ = best_start(task.added, start.plant(nominal), setting, train, stride=SCREEN_GRID_STRIDE)
            start = FittedCauses((task.added,) + start.causes, (points[index],) + start.u)
        fold_models.append(task_fit(task, start, train, FOLD_MAX_EVALUATIONS))
        features = replay_all(setting, fold_models[-1].plant(nominal), test)
        heldout[folds == k] = trial_errors(features, test)
        heldout_jump[folds == k] = jump_errors(features, test)
    return {"model": model, "heldout": heldout, "heldout_jump": heldout_jump, "folds": fold_models}


def relative_gain(error: float, reference: float) -> float:
    """1 - error / reference: the share of the ``reference`` error removed (0 without one)."""
    return 1.0 - error / reference if reference > 0 else 0.0


def significant_gain(before: np.ndarray, after: np.ndarray) -> bool:
    """Whether the held-out normalised residuals per trial ``after`` a step are significantly
    below those ``before`` it: the paired one-sided t-test over trials of the differences of
    their squares d_i = before_i^2 - after_i^2 (each trial's drop of its mean squared residual
    in noise units), t = mean(d) sqrt(n) / sd(d) >= t_``SIGNIFICANCE``(n - 1). The trial is
    the unit: a trial's residuals are correlated in time (its trace), trials are independent."""
    d = np.asarray(before, float) ** 2 - np.asarray(after, float) ** 2
    spread = d.std(ddof=1) if len(d) > 1 else 0.0
    if spread == 0.0:
        return bool(len(d) > 1 and d.mean() > 0.0)
    return bool(d.mean() * np.sqrt(len(d)) / spread >= student_t.ppf(SIGNIFICANCE, len(d) - 1))


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


