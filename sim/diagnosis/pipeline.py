"""The diagnosis's entry (``diagnose``): measure, replay, compare, select the causes, bound their
parameters (the steps: ``sim/diagnosis/__init__.py``)."""

from __future__ import annotations

import logging
from collections.abc import Callable

from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import MANIFEST, load_manifest
from impactqp.controller.model.validation import MAX_TRIALS, BadInputError, trial_count
from impactqp.sim.causes import Cause, default_causes
from impactqp.sim.plant import PlantParameters

from .comparison import error_analysis, predictor_errors
from .fitting import fit_report, jump_errors, trial_errors
from .intervals import excludes_nominal, open_sides, override_intervals, parameter_intervals, without_spurious
from .result import Diagnosis
from .search import select_causes
from .start_spread import start_spread
from .timing import timing_test
from .trials import load_trials, locate_jump_samples, replay_all


log = logging.getLogger(__name__)

STEPS = ("load and check the trials", "replay the nominal simulation", "select the causes",
         "bound the parameters", "compare the predictors")
"""The steps of ``diagnose``, in order, as its ``progress`` callback names them."""


def _usable_trials(directory, nominal: PlantParameters | None, causes: list[Cause] | None):
    """The usable trials of ``directory``, the skipped ones, the replay setting, the nominal
    plant for the robot's joints and the candidate causes (the defaults of the robot, its
    surface and its tool when None); bad input when no trial is usable."""
    trials, skipped, setting = load_trials(directory)
    if not trials:
        raise BadInputError(f"{directory}: no usable trial; the diagnosis needs at least 1 (skipped: {skipped})")
    joints = len(setting.choice.robot.joints)
    nominal = (nominal or PlantParameters()).for_joints(joints)
    causes = causes if causes is not None else default_causes(joints, setting.surface.friction, setting.choice.tool)
    names = [c.name for c in causes]
    if len(set(names)) != len(names):
        raise ValueError(f"candidate causes must have distinct names, got {names}")
    return trials, skipped, setting, nominal, causes


def parameter_rows(model, theta_intervals) -> list[dict]:
    """One row per fitted parameter: its cause, label, value and interval."""
    return [
        {"cause": c.name, "parameter": label, "value": float(value), "interval": interval}
        for c, u, intervals in zip(model.causes, model.u, theta_intervals)
        for label, value, interval in zip(c.labels, c.to_theta(u), intervals)
    ]


def diagnose(
    directory: str | Path,
    *,
    nominal: PlantParameters | None = None,
    causes: list[Cause] | None = None,
    jobs: int = 1,
    progress: Callable[[str], None] | None = None,
    max_trials: int = MAX_TRIALS,
    manifest: dict | None = None,
) -> Diagnosis:
    """Measure, replay, compare, select the causes, bound their parameters (the steps:
    ``sim/diagnosis/__init__.py``). As each of ``STEPS`` begins, ``progress(step)`` is called
    and the step is logged (a note: INFO, with its counts; the first once the trials are loaded
    and checked: bad input stays its one line); the search and the intervals log each
    model set and profile as it is done (``search``, ``intervals``). A dataset of more than
    ``max_trials`` trials is refused before any is read; ``manifest``: the dataset's manifest when
    the caller read it already (the command line's checks), else it is read here."""
    manifest = manifest if manifest is not None else load_manifest(Path(directory) / MANIFEST)
    trial_count(len(manifest["trials"]), max_trials, f"the dataset {directory}")

    def step(index: int, counts: str = "") -> None:
        if progress is not None and index > 0:  # the first is announced before the loading
            progress(STEPS[index])
        log.info("diagnose: step %d/%d %s%s", index + 1, len(STEPS), STEPS[index], counts)

    if progress is not None:
        progress(STEPS[0])
    trials, skipped, setting, nominal, causes = _usable_trials(directory, nominal, causes)
    step(0, f" ({len(trials)} usable, {len(skipped)} skipped)")
    step(1, f" ({len(trials)} trial(s))")
    trials = locate_jump_samples(trials, setting, nominal)
    if len(trials) == 1:
        step(4, " (one trial: no cause is selected)")
        return nominal_diagnosis(trials, skipped, setting, nominal)
    nominal_features = replay_all(setting, nominal, trials)
    nominal_jumps = np.array([f.detected_jump for f in nominal_features])
    baseline_errors = jump_errors(nominal_features, trials)
    baseline = (trial_errors(nominal_features, trials), baseline_errors)
    step(2, f" ({len(causes)} candidate causes)")
    selection = select_causes(causes, nominal, setting, trials, baseline, jobs)
    selected = bool(selection.model.causes)
    model = selection.model if selected else selection.best
    step(3, f" ({', '.join(c.name for c in model.causes) or 'no cause'})")
    model, theta_intervals = _bounded(model, selected, nominal, setting, trials, jobs)
    extended_plant = model.plant(nominal)
    extended_features, spreads, fit, timing = model_fit(setting, extended_plant, trials, jobs)
    explained = selected and _explains(model, theta_intervals, nominal, fit, timing)
    steps = selection.steps if explained else [{**s, "selected": False} for s in selection.steps]
    step(4)
    predictors, predictors_measured_impulse, predictions = predictor_errors(trials, setting)
    return Diagnosis(
        trials=trials,
        skipped=skipped,
        nominal_jumps=nominal_jumps,
        extended_jumps=np.array([f.detected_jump for f in extended_features]),
        baseline_errors=baseline_errors,
        candidates=selection.candidates,
        cause=model.causes[0].name,
        explained=explained,
        parameters=model.overrides(),
        predictors=predictors,
        predictors_measured_impulse=predictors_measured_impulse,
        predictions=predictions,
        analysis=error_analysis(trials, nominal_jumps),
        causes=[c.name for c in selection.model.causes] if explained else [],
        steps=steps,
        intervals=override_intervals(model, theta_intervals),
        parameter_intervals=parameter_rows(model, theta_intervals),
        open_sides=open_sides(model, theta_intervals, trials, nominal),
        extended_error=float(np.mean(selection.heldout_jump_errors)),
        gain_over_floor=selection.gain_over_floor,
        fit=fit,
        nominal_fit=fit_report(nominal_features, trials, start_spread(setting, nominal, trials, jobs)),
        trial_residuals=trial_errors(extended_features, trials, spreads),
        timing=timing,
        extended_plant=extended_plant,
        surface=setting.surface,
        choice=setting.choice,
    )


def _bounded(model, selected: bool, nominal: PlantParameters, setting, trials, jobs: int):
    """``model`` with its parameters' intervals; when it holds the selected causes, without the
    parameters the data do not move from their nominal values."""
    model, theta_intervals = parameter_intervals(model, nominal, setting, trials, jobs)
    if selected:
        model, theta_intervals = without_spurious(model, theta_intervals, nominal, setting, trials, jobs)
    return model, theta_intervals


def model_fit(setting, plant: PlantParameters, trials, jobs: int = 1) -> tuple[list, list[dict], dict, dict]:
    """How ``plant`` stands against ``trials``: its replays, their start spreads
    (``start_spread``), the fit test against the noise with them (``fitting.fit_report``) and the
    timing test (``timing.timing_test``)."""
    features = replay_all(setting, plant, trials)
    spreads = start_spread(setting, plant, trials, jobs)
    return features, spreads, fit_report(features, trials, spreads), timing_test(features, trials)


def _explains(model, theta_intervals, nominal: PlantParameters, fit: dict, timing: dict) -> bool:
    """Whether the selected causes explain the gap: their model fits the noise, holds one timing
    for every trial (``timing.timing_test``: every cause is one for all trials) and every named
    cause's interval excludes its nominal value (else the data do not say it moved)."""
    return fit["fits_noise"] and timing["consistent"] and all(excludes_nominal(model, theta_intervals, nominal))


def nominal_diagnosis(trials, skipped, setting, nominal: PlantParameters) -> Diagnosis:
    """The diagnosis of a single trial (one ``impactqp run`` on a robot): its nominal replay, its
    fit against the noise and the predictors' errors, and no cause: their selection holds trials
    out (cross-validation), which takes two."""
    nominal_features, spreads, fit, timing = model_fit(setting, nominal, trials)
    jumps = np.array([f.detected_jump for f in nominal_features])
    errors = jump_errors(nominal_features, trials)
    predictors, predictors_measured_impulse, predictions = predictor_errors(trials, setting)
    return Diagnosis(
        trials=trials, skipped=skipped, nominal_jumps=jumps, extended_jumps=jumps, baseline_errors=errors,
        candidates=[], cause="", explained=False, parameters={}, predictors=predictors,
        predictors_measured_impulse=predictors_measured_impulse, predictions=predictions,
        analysis=error_analysis(trials, jumps), causes=[], steps=[], intervals={}, parameter_intervals=[],
        open_sides=[], extended_error=float(np.mean(errors)), gain_over_floor=0.0, fit=fit, nominal_fit=fit,
        trial_residuals=trial_errors(nominal_features, trials, spreads), timing=timing,
        extended_plant=nominal, surface=setting.surface, choice=setting.choice,
    )
