"""The result of a diagnosis (``Diagnosis``): its JSON summary (``diagnose --json``, every key in
``docs/diagnosis.md``) and its message in plain words."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.sim.plant import PlantParameters

from .intervals import open_side_text
from .noise import BLOCKS, CHANNEL_LIMIT, FIT_LIMIT, channel_misfits, misfit_blocks, outlier_trials
from .selection import EXPLAINED_GAIN, STEP_GAIN, relative_gain
from .trials import MeasuredTrial


@dataclass
class Diagnosis:
    """What ``diagnose`` found: the trials used and skipped, the nominal and extended replays'
    jumps, the candidates and selection steps, the fitted causes with their intervals, the
    predictors' errors and the comparison (``error_analysis``), and the fit of the nominal and
    the final model against the noise (``fitting.fit_report``)."""

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
    gain_over_floor: float
    fit: dict
    nominal_fit: dict
    trial_residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    timing: dict = field(default_factory=lambda: {"consistent": True})  # ``timing.timing_test`` of the final model

    def outliers(self) -> list[str]:
        """The ids of the trials that stand out from the others (``noise.outlier_trials``), worst first."""
        return [self.trials[k].id for k in outlier_trials(self.trial_residuals)]

    def summary(self) -> dict:
        """The JSON summary (every key in ``docs/diagnosis.md``). The fitted values are results
        only when causes are named (``explained``): otherwise ``parameters``, ``intervals``,
        ``parameter_intervals`` and ``open_sides`` are empty, and the best model found, which
        explains nothing, is kept apart in ``best_model``."""
        baseline = float(np.mean(self.baseline_errors))
        fitted = {
            "parameters": self.parameters,
            "intervals": self.intervals,
            "parameter_intervals": self.parameter_intervals,
            "open_sides": self.open_sides,
        }
        return {
            "cause": self.cause,
            "causes": self.causes,
            "explained": self.explained,
            **(fitted if self.explained else {"parameters": {}, "intervals": {}, "parameter_intervals": [], "open_sides": []}),
            "best_model": None if self.explained or not self.parameter_intervals else {
                "causes": self.model_causes(), **fitted,
            },
            "steps": self.steps,
            "baseline_error": baseline,
            "extended_error": self.extended_error,
            "gain": relative_gain(self.extended_error, baseline),
            "gain_over_floor": self.gain_over_floor,
            "fit": self.fit,
            "nominal_fit": self.nominal_fit,
            "candidates": self.candidates,
            "trials": len(self.trials),
            "trial_residuals": [
                {"id": t.id, "residual": float(r)} for t, r in zip(self.trials, self.trial_residuals)
            ],
            "outlier_trials": self.outliers(),
            "timing": self.timing,
            "skipped": self.skipped,
            "predictors": self.predictors,
            "predictors_measured_impulse": self.predictors_measured_impulse,
            "analysis": self.analysis,
            "message": self.message(),
        }

    def message(self) -> str:
        if len(self.trials) == 1:
            return self.single_trial_message()
        text = self.explained_message() if self.explained else self.unexplained_message()
        return text + self.timing_text() + self.outlier_text()

    def outlier_text(self) -> str:
        """A sentence naming the trials that stand out (empty when none does)."""
        outliers = outlier_trials(self.trial_residuals)
        if not outliers:
            return ""
        median = float(np.median(self.trial_residuals))
        named = ", ".join(f"{self.trials[k].id} ({self.trial_residuals[k]:.1f})" for k in outliers)
        return (
            f" {'Trial' if len(outliers) == 1 else 'Trials'} {named} stand{'s' if len(outliers) == 1 else ''} out: "
            f"residual in noise units against a median of {median:.1f} over the trials; look at "
            f"{'its log' if len(outliers) == 1 else 'their logs'} (JSON key trial_residuals)."
        )

    def timing_text(self) -> str:
        """A sentence when the trials' timings differ (``timing.timing_test``; empty otherwise):
        the shifts that line each trial's replayed velocity trace up with the measured one, and
        the test that refuses one timing for all trials."""
        timing = self.timing
        if timing["consistent"]:
            return ""
        shifts = [(t.id, s) for t, s in zip(self.trials, timing["shifts"]) if s is not None]
        low, high = min(shifts, key=lambda x: x[1]), max(shifts, key=lambda x: x[1])
        return (
            f" The trials' timings differ: the measured velocities lag the replay's by {low[1]:.1f} ({low[0]}) to "
            f"{high[1]:.1f} samples ({high[0]}), more than the replay's own timing allows (homogeneity test: "
            f"chi-square {timing['statistic']:.1f} on {timing['dof']} degrees of freedom, p = {timing['p_value']:.2g}); "
            "every candidate cause is one for all trials: look for a delay that changes from trial to trial "
            "(the logs' clocks, dropped or repeated samples; JSON key timing)."
        )

    def explained_message(self) -> str:
        """Plain words for named causes: what fitting them gains, their values and intervals."""
        baseline = float(np.mean(self.baseline_errors))
        gain = relative_gain(self.extended_error, baseline)
        named = " + ".join(f"'{c}'" for c in self.causes)
        text = (
            f"The gap between the simulation and the measurements is explained by {named}: fitting "
            f"{'it' if len(self.causes) == 1 else 'them'} lowers the held-out average error from "
            f"{baseline:.4f} to {self.extended_error:.4f} rad/s ({100 * gain:.0f} % gain; "
            f"{100 * self.gain_over_floor:.0f} % of the excess over the noise floor), and the fitted model "
            f"matches the data within the noise ({fit_text(self.fit)})."
        )
        for p in self.parameter_intervals:
            text += f" {p['parameter']}: {p['value']:.4g}, 95 % interval {interval_text(p['interval'])}."
        intervals = {p["parameter"]: p["interval"] for p in self.parameter_intervals}
        for o in self.open_sides:
            text += " " + open_side_text(o, intervals[o["parameter"]])
        return text


    def single_trial_message(self) -> str:
        """Plain words for one trial: how the nominal simulation fits it; no cause is selected."""
        verdict = "matches it within the noise" if self.nominal_fit["fits_noise"] else "does not match it"
        return (
            f"One trial: the nominal simulation, replayed with its commands, {verdict} "
            f"({fit_text(self.nominal_fit)}; average error (26) {float(np.mean(self.baseline_errors)):.4f} rad/s). "
            "No cause is selected: the selection holds trials out, which takes at least 2 trials."
        )

    def unexplained_message(self) -> str:
        """Plain words when nothing explains the gap: the data fit the nominal within the noise
        (whatever the best model found does), or the best model found still misfits (which
        block, by how much), or misses the trials' timings (``timing_text`` follows), or the
        causes remove too little of the excess over the noise floor."""
        model = " + ".join(f"'{name}'" for name in self.model_causes())
        if self.nominal_fit["fits_noise"]:
            gain = max((c["gain"] for c in self.candidates), default=0.0)
            return (
                "No candidate cause is needed: the nominal simulation already matches the data within the noise "
                f"({fit_text(self.nominal_fit)}); the best candidate, {model}, lowers the held-out residual by "
                f"{100 * gain:.0f} % (a cause needs {100 * STEP_GAIN:.0f} %) and removes "
                f"{100 * self.gain_over_floor:.0f} % of the excess over the noise floor "
                f"(the causes need {100 * EXPLAINED_GAIN:.0f} %)."
            )
        misfits = misfit_blocks(self.fit)
        if misfits or channel_misfits(self.fit):
            return (
                f"No candidate cause explains the gap, and the best model found ({model}) does not fit the "
                f"data: {misfit_text(self.fit)}. Something outside the candidate causes is at work, e.g. in "
                f"{where_misfit(self.fit)}; its fitted values mean nothing."
            )
        if self.fit["fits_noise"] and not self.timing["consistent"]:
            return (
                f"No candidate cause explains the gap: the best model found ({model}) matches the data within the "
                f"noise on average ({fit_text(self.fit)}), but not each trial's timing."
            )
        if self.fit["fits_noise"] and self.gain_over_floor >= EXPLAINED_GAIN:
            return (
                f"No candidate cause explains the gap: the best model found ({model}) fits the noise, but the "
                "95 % interval of every parameter of one of its causes contains that parameter's nominal value, "
                "so the data do not show the plant moved away from the nominal; more trials would tell."
            )
        return (
            f"No candidate cause explains the gap: the best one, {model}, removes only "
            f"{100 * self.gain_over_floor:.0f} % of the nominal simulation's excess error over the noise floor "
            f"(threshold {100 * EXPLAINED_GAIN:.0f} %); the nominal simulation misfits ({fit_text(self.nominal_fit)})."
        )

    def model_causes(self) -> list[str]:
        """The causes of the reported model (``parameter_intervals``), in order."""
        names = list(dict.fromkeys(p["cause"] for p in self.parameter_intervals))
        return names or [self.cause]


def misfit_text(fit: dict) -> str:
    """What misfits in a fit, in words: each block beyond ``FIT_LIMIT``, and the worst channel
    when it is beyond ``CHANNEL_LIMIT`` (a fault of one joint that a block's mean may hide)."""
    parts = [f"the {b} residual is {fit[b]:.1f} times the noise" for b in misfit_blocks(fit)]
    limits = f"a block that fits stays within {FIT_LIMIT:g}"
    if channel_misfits(fit):
        channel = fit["worst_channel"]
        parts.append(f"the {channel['block']} residual of {channel['channel']} alone is {channel['value']:.1f}")
        limits += f", one joint's channel within {CHANNEL_LIMIT:g}"
    return ", ".join(parts) + f" ({limits})"


def where_misfit(fit: dict) -> str:
    """Where to look first: the worst channel when it misfits, else the worst block's signal."""
    if channel_misfits(fit):
        return f"the {fit['worst_channel']['block']} of {fit['worst_channel']['channel']}"
    return f"the {misfit_blocks(fit)[0]} signal"


def fit_text(fit: dict) -> str:
    """The normalised residual of each block of a fit, in words."""
    return ", ".join(f"{b} {fit[b]:.1f}" for b in BLOCKS if b in fit) + " noise units"


def interval_text(interval) -> str:
    low, high = interval
    if low is None and high is None:
        return "unbounded both ways"
    if low is None:
        return f"at most {high:.4g} (open below)"
    if high is None:
        return f"at least {low:.4g} (open above)"
    return f"[{low:.4g}, {high:.4g}]"
