"""The result of a diagnosis (``Diagnosis``): its JSON summary (``diagnose --json``, every key in
``docs/diagnosis.md``) and its message in plain words."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.sim.plant import PlantParameters

from .selection import EXPLAINED_GAIN, relative_gain
from .trials import MeasuredTrial


@dataclass
class Diagnosis:
    """What ``diagnose`` found: the trials used and skipped, the nominal and extended replays'
    jumps, the candidates and selection steps, the fitted causes with their intervals, the
    predictors' errors and the comparison (``error_analysis``)."""

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
    choice: RobotChoice

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
