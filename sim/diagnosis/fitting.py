"""Fitting causes to the trials: residuals of a replay, and bounded least squares over them.

The residuals per trial (``residuals``) are the jump error (7) / ``SIGMA_JUMP`` (both jumps read
at the trial's ``jump_samples``), the error of the mean joint torque over the torque window
before contact (7) / ``SIGMA_TORQUE``, and, with force data, the impulse error (3) /
``SIGMA_IMPULSE`` and the contact duration error / ``SIGMA_DURATION``. A fit (``fit``) minimises
their sum of squares over the replays with ``scipy.optimize.minimize`` (Powell, bounded), from
the best point of each cause's grid (``best_start``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from impactqp.controller.model.jump import average_prediction_error
from impactqp.sim.causes import Cause
from impactqp.sim.plant import PlantParameters

from .trials import MeasuredTrial, ReplayFeatures, ReplaySetting, replay_all

SIGMA_JUMP = 0.005
SIGMA_TORQUE = 0.05
SIGMA_IMPULSE = 0.02
SIGMA_DURATION = 1e-3
FIT_XTOL = 2e-3
POWELL_STEPS = 6  # Powell's first step along each parameter: its range / 6


def residuals(features: list[ReplayFeatures], trials: list[MeasuredTrial]) -> np.ndarray:
    """The residual vector of the replays ``features`` against ``trials`` (module docstring)."""
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


def best_start(cause: Cause, base: PlantParameters, setting, trials, features_of_grid=None):
    """The grid point of ``cause`` (on top of ``base``) with the least cost over ``trials``:
    (its index, the grid, the replay features at every grid point)."""
    points = cause.grid(base)
    if features_of_grid is None:
        features_of_grid = [replay_all(setting, cause.plant(base, u), trials) for u in points]
    costs = [np.sum(residuals(f, trials) ** 2) for f in features_of_grid]
    return int(np.argmin(costs)), points, features_of_grid
