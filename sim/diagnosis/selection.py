"""Cross-validation of causes on held-out error: the tasks the search (``search``) runs.

The held-out normalised residual (every block in noise units, ``fitting.trial_errors``; over
trials, their quadratic mean) of K-fold cross-validation over trials (K = min(``MAX_FOLDS``,
trials)):

- ``cross_validate_cause``: one candidate added on top of the causes already chosen (per fold,
  on top of the chosen causes fitted without that fold);
- ``screen_cause``: the cheap screen before it, a short local fit of the candidate together with
  the chosen causes, in sample;
- ``cross_validate_model``: a set of causes refitted jointly without each fold (a removal or a
  refinement of the search).

A step gains ``STEP_GAIN`` over the error before it (``selection_step``); the causes must remove
``EXPLAINED_GAIN`` of the nominal's excess over the noise floor (``gain_over_floor``). The rules
and their reasons: ``docs/diagnosis.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters

from .fitting import FittedCauses, best_start, fit, jump_errors, trial_errors
from .noise import quadratic_mean
from .trials import MeasuredTrial, ReplaySetting, replay_all

EXPLAINED_GAIN = 0.20  # the causes must remove 20 % of the nominal's held-out excess over the noise floor
NOISE_FLOOR = 1.0  # the normalised residual of a model that fits: the noise itself
STEP_GAIN = 0.20  # every further cause by 20 % of the held-out error of the causes before it
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
    """One candidate to cross-validate on top of the causes already chosen (a process task):
    ``bases[k]`` is the plant of the chosen causes fitted without fold k, ``base_all`` the one
    fitted on all trials; ``start`` the candidate's start vector (its screen), None: the best
    grid point of each fit's trials."""

    cause: Cause
    bases: tuple[PlantParameters, ...]
    base_all: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]
    start: np.ndarray | None = None


def cross_validate_cause(task: CandidateTask) -> dict:
    """Held-out errors of one candidate added to the causes already chosen (one process task).

    Per fold k: a fit of the candidate on the training trials on top of ``bases[k]``, from
    ``start`` or else the best grid point on them, and its replay of the held-out trials gives
    their normalised residuals (``heldout``) and errors (26) (``heldout_jump``). Then the
    candidate is fitted on all trials on top of ``base_all``."""
    cause, setting, trials = task.cause, task.setting, list(task.trials)
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    heldout_jump = np.empty(len(trials))
    u_folds = []
    shared = None  # grid features on all trials, when every fold shares the base (first step)
    if task.start is None and all(b == task.base_all for b in task.bases):
        _, _, shared = best_start(cause, task.base_all, setting, trials)

    def start(base, subset, indices):
        if task.start is not None:
            return task.start
        grid = [[g[i] for i in indices] for g in shared] if shared is not None else None
        i, points, _ = best_start(cause, base, setting, subset, grid)
        return points[i]

    for k in np.unique(folds):
        train_idx = [i for i, f in enumerate(folds) if f != k]
        train = [trials[i] for i in train_idx]
        test = [t for t, f in zip(trials, folds) if f == k]
        base = task.bases[k]
        fitted = fit(FittedCauses((cause,), (start(base, train, train_idx),)), base, setting, train, FOLD_MAX_EVALUATIONS)
        u_folds.append(fitted.u[0])
        features = replay_all(setting, fitted.plant(base), test)
        heldout[folds == k] = trial_errors(features, test)
        heldout_jump[folds == k] = jump_errors(features, test)
    u0 = start(task.base_all, trials, range(len(trials)))
    u_all = fit(FittedCauses((cause,), (u0,)), task.base_all, setting, trials, FIT_MAX_EVALUATIONS).u[0]
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
    """A set of causes to cross-validate as a whole (a process task): ``model`` is the start of
    every fit, on top of ``nominal``."""

    model: FittedCauses
    nominal: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]


def cross_validate_model(task: ModelTask) -> dict:
    """The causes of ``model`` refitted jointly on all trials (``model``), and without each
    fold k from there: the held-out normalised residuals and errors (26) of the fold's trials
    (``heldout``, ``heldout_jump``), the causes fitted without each fold (``folds``) and their
    plants (``bases``)."""
    setting, trials, nominal = task.setting, list(task.trials), task.nominal
    model = fit(task.model, nominal, setting, trials, JOINT_MAX_EVALUATIONS)
    folds = fold_of(trials)
    heldout = np.empty(len(trials))
    heldout_jump = np.empty(len(trials))
    bases, fold_models = [], []
    for k in np.unique(folds):
        train = [t for t, f in zip(trials, folds) if f != k]
        test = [t for t, f in zip(trials, folds) if f == k]
        fold_models.append(fit(model, nominal, setting, train, FOLD_MAX_EVALUATIONS))
        bases.append(fold_models[-1].plant(nominal))
        features = replay_all(setting, bases[-1], test)
        heldout[folds == k] = trial_errors(features, test)
        heldout_jump[folds == k] = jump_errors(features, test)
    return {"model": model, "heldout": heldout, "heldout_jump": heldout_jump, "bases": bases, "folds": fold_models}


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


