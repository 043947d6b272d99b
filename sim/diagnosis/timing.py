"""Whether one timing holds for every trial: the shift of each trial's velocity trace against its
replay (``trial_shift``) and the test that the shifts are one up to their noise (``timing_test``).

Every candidate cause is one for the whole dataset: a sensor delay, a velocity filter, a plant
that yields slowly act alike on every trial. A log whose timing differs from trial to trial (dq
logged late by a number of samples that changes per trial: a clock, a buffer, a dropped sample)
is outside every candidate, yet a single delay or filter may come close to fitting it on
average. Under a model that holds the data, each trial's measured velocity trace (``trials.
impact_trace``: the TRACE_LENGTH samples after the pre-impact one, minus the pre-impact mean) is
its replay's, up to the sensor noise and the replay's own timing; so the shift that best lines
the replay up with the measurement is the same in every trial within those two errors.

- **Shift of trial i**: s_i = argmin_s S_i(s), S_i(s) = sum_{k, j} (m_kj - r_kj(s))^2 / sigma_j^2,
  m the measured velocity trace, r(s) the replayed one read s samples late (linear
  interpolation, ``sim.sensor.delayed``; before the trace its pre-impact level 0, after it its
  last sample), sigma_j joint j's sensor std of a trace sample (``noise.BlockNoise.trace``); over
  |s| <= ``MAX_SHIFT`` samples, from the best point of a grid of ``GRID_STEP`` then a bounded
  scalar minimisation around it.
- **Its variance**: v_i = 1 / sum_{k, j} r'_kj(s_i)^2 / sigma_j^2 + tau^2: the noise's part (the
  inverse of half the curvature of S_i, Gauss-Newton; r' the trace's slope per sample) and the
  replay's timing, one error for the whole trace: the replay touches the wall at one of its
  physics steps, which its noisy start state (a mean of noisy velocities) moves by a step or
  two, so tau = one physics step, ``sim.scene.DEFAULT_TIMESTEP`` / the control period (0.25
  sample at 1 kHz): a right model's shifts, about their dataset's mean, fall on whole physics
  steps (their measured spread: docs/diagnosis.md, "One timing for every trial"). A trial
  whose replayed velocity does not change (no slope) has no shift.
- **Test** (Cochran's homogeneity test): the weighted mean s = sum(s_i / v_i) / sum(1 / v_i) and
  Q = sum (s_i - s)^2 / v_i, chi-square with n - 1 degrees of freedom when every trial has one
  timing; the timings differ when P(chi2_{n-1} >= Q) < ``TIMING_LEVEL``. The trial is the unit
  (its trace samples share one timing error), so a shift shared by every trial (a sensor delay the
  model lacks) does not count, only their spread.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import chi2

from impactqp.sim.sensor import delayed
from impactqp.sim.scene import DEFAULT_TIMESTEP

MAX_SHIFT = 8.0  # samples: half the trace (TRACE_LENGTH = 16)
GRID_STEP = 0.25  # samples: the grid before the local minimisation of a shift
TIMING_LEVEL = 1e-3  # the timings differ when the homogeneity test's p-value is below this


def shifted(trace: np.ndarray, samples: float) -> np.ndarray:
    """The velocity ``trace`` (samples x joints, from the first sample after the pre-impact one)
    read ``samples`` samples late: its pre-impact level 0 comes first."""
    padded = np.vstack([np.zeros((1, trace.shape[1])), trace])
    return delayed(padded, samples)[1:]


def trial_shift(measured: np.ndarray, replayed: np.ndarray, sigma: np.ndarray, timing: float) -> tuple[float, float]:
    """(s_i, v_i) of the module docstring for one trial's measured and replayed velocity traces
    (samples x joints), its joints' sensor stds ``sigma`` and the replay's timing std ``timing``
    (tau, samples); (0, inf) when the replay has no slope."""
    def cost(s: float) -> float:
        return float(np.sum(((measured - shifted(replayed, s)) / sigma) ** 2))

    grid = np.arange(-MAX_SHIFT, MAX_SHIFT + GRID_STEP / 2, GRID_STEP)
    start = float(grid[int(np.argmin([cost(s) for s in grid]))])
    bounds = (max(start - GRID_STEP, -MAX_SHIFT), min(start + GRID_STEP, MAX_SHIFT))
    s = float(minimize_scalar(cost, bounds=bounds, method="bounded", options={"xatol": 1e-3}).x)
    slope = np.gradient(shifted(replayed, s), axis=0)
    information = float(np.sum((slope / sigma) ** 2))
    if information == 0.0:
        return 0.0, float("inf")
    return s, 1.0 / information + timing**2


def timing_test(features, trials) -> dict:
    """The per-trial shifts of the velocity traces of the replays ``features`` against ``trials``
    and Cochran's test that they are one (module docstring): ``{shifts, stds, statistic, dof,
    p_value, consistent}``, the shifts in samples (a positive one: the measurement is late
    against the replay; None for a trial without one). With fewer than 2 trials that have a
    shift, nothing is tested (consistent, p-value 1)."""
    shifts, variances = [], []
    for f, trial in zip(features, trials):
        joints = len(trial.dq0)
        sigma = np.asarray(trial.noise.trace[:joints], float)
        timing = DEFAULT_TIMESTEP / trial.control_period
        s, v = trial_shift(trial.reference_trace[:, :joints], f.trace[:, :joints], sigma, timing)
        shifts.append(s)
        variances.append(v)
    s, v = np.array(shifts), np.array(variances)
    known = np.isfinite(v)
    dof = int(np.sum(known)) - 1
    statistic, p_value = 0.0, 1.0
    if dof >= 1:
        w = 1.0 / v[known]
        mean = float(np.sum(w * s[known]) / np.sum(w))
        statistic = float(np.sum(w * (s[known] - mean) ** 2))
        p_value = float(chi2.sf(statistic, dof))
    return {
        "shifts": [float(x) if k else None for x, k in zip(s, known)],
        "stds": [float(np.sqrt(x)) if k else None for x, k in zip(v, known)],
        "statistic": statistic,
        "dof": max(dof, 0),
        "p_value": p_value,
        "consistent": bool(p_value >= TIMING_LEVEL),
    }
