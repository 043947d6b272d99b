"""Fitting causes to the trials: residuals of a replay, and bounded least squares over them.

The residuals per trial (``residuals``) are the jump error (one per joint; both jumps read at the
trial's ``jump_samples``), the error of the mean joint torque over the torque window before contact
(one per joint), with force data the impulse error (3) and the contact duration error, and the error of the
impact trace (``trials.impact_trace``: velocities and torques, TRACE_LENGTH samples x 2 per joint), each divided by its
block's noise std read from the data (``noise.estimate_noise``), so every block counts by its
noise. A trial's error (``trial_errors``) is the root mean square of its residuals: the
normalised residual the selection compares. A fit (``fit``) minimises
their sum of squares over the replays with ``scipy.optimize.minimize`` (Powell, bounded), from
the best point of each cause's grid (``best_start``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from impactqp.controller.model.jump_error import average_prediction_error
from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters

from .noise import BLOCKS, fits_noise, trace_std
from .trials import MeasuredTrial, ReplayFeatures, ReplaySetting, replay_all

FIT_XTOL = 2e-3
POWELL_STEPS = 6  # Powell's first step along each parameter: its range / 6


def residuals(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    """The residual vector of the replays ``features`` against ``trials`` (module docstring)."""
    return np.concatenate([trial_residuals(f, trial) for f, trial in zip(features, trials)])


def trial_residuals(f: ReplayFeatures, trial: MeasuredTrial, spread: dict | None = None) -> np.ndarray:
    """The residuals of one replay in noise units, its blocks (``residual_blocks``, with the
    trial's start ``spread`` when given) in the order of ``noise.BLOCKS``."""
    return np.concatenate(list(residual_blocks(f, trial, spread).values()))


def residual_blocks(f: ReplayFeatures, trial: MeasuredTrial, spread: dict | None = None) -> dict[str, np.ndarray]:
    """The residuals of one replay in noise units per block: jump and torque (one per joint), then
    with force data impulse (3) and duration (1), and the impact trace (TRACE_LENGTH x 2 per joint, each
    sample over its own std, ``noise.trace_std``). With the trial's ``spread``
    (``start_spread.start_spread``: block -> the replay's start spread s_i per residual), each
    residual is divided by max(1, s_i) too: its std where the replay's start moves it more than
    the noise does."""
    noise = trial.noise
    blocks = {"jump": (f.jump - trial.reference) / noise.jump, "torque": (f.torque - trial.torque) / noise.torque}
    if trial.impulse is not None:  # a replay without a force contact counts as a zero impulse
        impulse, duration = (np.zeros(3), 0.0) if f.impulse is None else (f.impulse, f.duration)
        blocks["impulse"] = (impulse - trial.impulse) / noise.impulse
        blocks["duration"] = np.array([(duration - trial.duration) / noise.duration])
    reference = trial.reference_trace
    blocks["trace"] = ((f.trace - reference) / trace_std(reference, noise.trace)).ravel()
    if spread:
        blocks = {name: value / np.maximum(spread.get(name, 0.0), 1.0) for name, value in blocks.items()}
    return blocks


def trial_errors(features: list[ReplayFeatures], trials: list[MeasuredTrial], spreads: list[dict] | None = None) -> np.ndarray:
    """The normalised residual of each trial: root mean square of its residuals in noise units
    (``residual_blocks``, with each trial's start spread of ``spreads`` when given)."""
    spreads = spreads or [None] * len(trials)
    return np.array([np.sqrt(np.mean(trial_residuals(f, t, s) ** 2)) for f, t, s in zip(features, trials, spreads)])


def fit_report(features: list[ReplayFeatures], trials: list[MeasuredTrial], spreads: list[dict] | None = None) -> dict:
    """The normalised residual (root mean square in noise units over the trials) of every block
    (``residual_blocks``, with each trial's start spread of ``spreads`` when given; impulse and
    duration only with force data) and whether all are within the noise (``noise.fits_noise``):
    the JSON ``fit`` and ``nominal_fit``."""
    spreads = spreads or [None] * len(trials)
    rows = [residual_blocks(f, t, s) for f, t, s in zip(features, trials, spreads)]
    report = {}
    for block in BLOCKS:
        values = [r[block] for r in rows if block in r]
        if values:
            report[block] = float(np.sqrt(np.mean(np.concatenate(values) ** 2)))
    report["worst_channel"] = worst_channel(rows, len(trials[0].reference))
    return {**report, "fits_noise": fits_noise(report)}


def worst_channel(rows: list[dict[str, np.ndarray]], joints: int) -> dict:
    """The channel with the largest normalised residual over the trials (root mean square in
    noise units): one joint's jump or torque, or one joint's velocity or torque trace (the trace
    block's columns: the joints' velocities, then their torques), as ``{block, channel, value}``."""
    channels = {
        "jump": np.array([r["jump"] for r in rows]),
        "torque": np.array([r["torque"] for r in rows]),
        "trace": np.concatenate([r["trace"].reshape(-1, 2 * joints) for r in rows]),
    }
    worst = {"block": "", "channel": "", "value": 0.0}
    for block, residuals in channels.items():
        rms = np.sqrt(np.mean(residuals**2, axis=0))
        k = int(np.argmax(rms))
        if rms[k] > worst["value"]:
            name = f"joint {k % joints + 1}" + ("" if block != "trace" else " velocity" if k < joints else " torque")
            worst = {"block": block, "channel": name, "value": float(rms[k])}
    return worst


def residual_sizes(trials: list[MeasuredTrial]) -> list[int]:
    """How many residuals each trial contributes (``residuals``)."""
    return [
        len(t.reference) + len(t.torque) + (4 if t.impulse is not None else 0) + t.reference_trace.size for t in trials
    ]


def jump_errors(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    """Average error (26) of each replayed jump against the measured one, both read at the
    trial's ``jump_samples``."""
    return np.array([average_prediction_error(f.jump, t.reference) for f, t in zip(features, trials)])


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


def cost_of(plant: PlantParameters, setting: ReplaySetting, trials) -> float:
    return float(np.sum(residuals(replay_all(setting, plant, trials), trials) ** 2))


def fit(model: FittedCauses, base: PlantParameters, setting, trials, max_evaluations: int) -> FittedCauses:
    """Least squares over the replays of ``trials``: minimise the sum of squared residuals over
    the vectors of ``model`` (its current vectors are the start), with the plant ``base`` under
    them, within the bounds, with Powell's derivative-free method (the replayed features are
    only piecewise smooth in the parameters: the contact duration and impulse end at a force
    sample that can switch, which defeats finite-difference Jacobians). Returns the best point
    evaluated."""
    lo, hi = model.bounds()
    best = {"cost": np.inf, "u": np.clip(model.vector(), lo, hi)}

    def cost(u):
        value = cost_of(model.with_vector(u).plant(base), setting, trials)
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


def best_start(cause: Cause, base: PlantParameters, setting, trials, features_of_grid=None, stride: int = 1):
    """The grid point of ``cause`` (on top of ``base``) with the least cost over ``trials``:
    (its index, the grid, the replay features at every grid point). ``stride`` > 1 keeps the
    nominal point and every ``stride``-th point of the rest (a coarser grid)."""
    points = cause.grid(base)
    points = points[:1] + points[1::stride]
    if features_of_grid is None:
        features_of_grid = [replay_all(setting, cause.plant(base, u), trials) for u in points]
    costs = [np.sum(residuals(f, trials) ** 2) for f in features_of_grid]
    return int(np.argmin(costs)), points, features_of_grid
