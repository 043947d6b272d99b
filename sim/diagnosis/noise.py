"""The noise of the compared signals, read from the data (``estimate_noise``), and the fit of a
model against it (``fit_report``).

The diagnosis compares five signal blocks per trial (``fitting.residuals``): the jump (one per
joint), the mean torque before contact (one per joint), with force data the impulse (3) and the
contact duration, and
the impact trace of the velocities and torques (``trials.impact_trace``). Each block's noise std is estimated from the
dataset itself, never from a constant:

- **sensor scatter**: the per-sample noise variance of dq and tau from the samples before the
  impact (second differences remove a smooth motion and leave 6 sigma^2 of white noise; a
  robust median, 1.4826 median |d2| / sqrt 6), at least q / sqrt 12 for a signal quantised to
  a step q (a low-noise encoder: most second differences are 0): the dataset's declared
  ``encoder_step`` for dq, else the step common to every logged value of the joint over all
  trials (``quantisation_step``), propagated through the block's averages: a jump
  is a mean of 2 POST_HALF_WIDTH + 1 samples minus a mean of PRE_SAMPLES, its std is
  sigma sqrt(1 / PRE_SAMPLES + 1 / (2 POST_HALF_WIDTH + 1)); the torque is a mean over its
  window, std sigma / sqrt(window), times ``REPLAY_TORQUE_FACTOR``: the replay's start
  velocity is a mean of noisy samples, and the servo's torque answers its error over the whole
  window (the right model's torque residual over the sensor scatter alone is 1.8-2.7 on
  simulated datasets, ``docs/diagnosis.md``); a trace sample is one sample minus the
  pre-impact mean, std sigma sqrt(1 + 1 / PRE_SAMPLES), combined per sample with a timing
  term (``trace_std``): the replay starts from a mean of noisy velocities, so it reaches the
  wall a fraction of a sample early or late, which moves each trace sample by that fraction
  times its slope; with ``REPLAY_TIMING_SAMPLES`` = 0.1 sample the right model reads about
  1 (``docs/diagnosis.md``). The trace has no repeat term: repeats hit the wall at moments that
  differ within a sample, which their own replays reproduce;
- **repeat-to-repeat variation**: the pooled within-condition std (same posture, normal and
  tangential speed) of every other block, which also carries what the sensors' scatter does not (the
  force log's, the start state's);
- **floors**: ``DURATION_FLOOR_SAMPLES`` force-log sample periods for the duration (it ends at
  two threshold crossings, each quantised to a sample, and the replay's start moves them),
  ``IMPULSE_FLOOR_SHARE`` of the root mean square impulse for the impulse.

Each block's std is the largest of those it has. The normalised residual of a block is the root
mean square of its residuals in noise units over the trials, and of a channel (one joint's jump
or torque, one joint's velocity or torque trace) the same over that channel's residuals; a model
fits the noise when every block's is at most ``FIT_LIMIT`` and every channel's at most
``CHANNEL_LIMIT`` (a model with the right causes reads about 1 to 2: the replay's
start state carries its own noise). Where a replay is far more sensitive to its start than
that, the fit test divides each residual by its start spread too (``start_spread``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.measured.impact import POST_HALF_WIDTH, PRE_SAMPLES

BLOCKS = ("jump", "torque", "impulse", "duration", "trace")
FIT_LIMIT = 3.0
CHANNEL_LIMIT = 2.0 * FIT_LIMIT  # one joint's channel of a block: fewer residuals, a wider spread
OUTLIER_FACTOR = 2.0  # a trial whose residual is this many times the trials' median (and misfits) stands out
OUTLIER_SPREADS = 4.0  # ... or this many robust standard deviations above that median (``outlier_trials``)
IMPULSE_FLOOR_SHARE = 0.005
REPLAY_TORQUE_FACTOR = 2.5  # without repeats: the torque residual of a right model over the sensor scatter's
REPLAY_TIMING_SAMPLES = 0.1  # the replay's contact moment is known to a tenth of a sample (its start state is noisy)
DURATION_FLOOR_SAMPLES = 4  # a duration's resolution: force-log samples (two threshold crossings, the replay's start)
TINY = {"jump": 1e-5, "torque": 1e-4, "impulse": 1e-5, "duration": 1e-5, "trace": 1e-5}  # noise-free data: no 0 divisions
MAD_TO_STD = 1.4826
STEP_TOLERANCE = 1e-3  # a quantised signal's gaps are whole multiples of its step within this share of it
STEP_RESOLUTION = 1e-9  # relative: gaps below this share of a signal's magnitude are rounding, not a step


@dataclass(frozen=True)
class BlockNoise:
    """Noise std of each compared block: jump (one per joint, rad/s), torque (one per joint, N m),
    impulse (3, N s), duration (s), impact trace (2 per joint and sample: the joint velocities,
    rad/s, then the joint torques, N m; the sensor term of ``trace_std``)."""

    jump: np.ndarray
    torque: np.ndarray
    impulse: np.ndarray
    duration: float
    trace: np.ndarray


def sample_variance(samples: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Per-column variance of the white noise on a smooth signal (module docstring), at least
    the quantisation's, step^2 / 12 (the variance of a rounding error spread evenly over one
    ``step``, per column, 0: not quantised; ``quantisation_step``), which a low-noise encoder's
    median second difference of 0 would otherwise hide. A column whose median |second
    difference| is 0 but not every one (mostly flat) falls back to their mean square, 6 sigma^2:
    the noise never reads 0 while the signal moves off its smooth path. Zeros for fewer than 3
    samples."""
    if len(samples) < 3:
        return np.zeros(samples.shape[1])
    second = samples[2:] - 2.0 * samples[1:-1] + samples[:-2]
    scatter = (MAD_TO_STD * np.median(np.abs(second), axis=0)) ** 2 / 6.0
    scatter = np.where(scatter > 0.0, scatter, np.mean(second**2, axis=0) / 6.0)
    return np.maximum(scatter, np.asarray(step, float) ** 2 / 12.0)


def quantisation_step(samples: np.ndarray) -> np.ndarray:
    """Per column, the step common to its values: the smallest gap q between two distinct values
    when every gap is a whole multiple of it (within ``STEP_TOLERANCE`` q), an encoder's step;
    0 when the gaps share no step (a signal that is not quantised) or the column is constant.
    Gaps below ``STEP_RESOLUTION`` of the column's largest magnitude are the same value written
    twice (rounding), not a step."""
    steps = np.zeros(samples.shape[1])
    for j in range(samples.shape[1]):
        values = np.unique(samples[:, j])
        gaps = np.diff(values)
        gaps = gaps[gaps > STEP_RESOLUTION * np.max(np.abs(values), initial=0.0)]
        if gaps.size == 0:
            continue
        multiples = gaps / gaps.min()
        if np.all(np.abs(multiples - np.round(multiples)) <= STEP_TOLERANCE):
            steps[j] = gaps.min()
    return steps


def repeat_std(trials, value) -> np.ndarray | None:
    """Pooled within-condition std of ``value(trial)`` over conditions with repeats (None
    without any repeat)."""
    groups: dict = {}
    for t in trials:
        groups.setdefault((t.posture, t.reference_speed, t.tangential_speed), []).append(np.atleast_1d(value(t)))
    squares, dof = 0.0, 0
    for group in groups.values():
        if len(group) > 1:
            x = np.array(group, dtype=float)
            squares = squares + np.sum((x - x.mean(axis=0)) ** 2, axis=0)
            dof += len(group) - 1
    return np.sqrt(squares / dof) if dof else None


def largest(name: str, *estimates) -> np.ndarray:
    """The largest of the available ``estimates`` (None: not available), at least ``TINY``."""
    result = np.asarray(TINY[name], float)
    for estimate in estimates:
        if estimate is not None:
            result = np.maximum(result, np.asarray(estimate, float))
    return result


def estimate_noise(trials) -> BlockNoise:
    """The noise std of every block from the trials' scatter and repeats (module docstring)."""
    dq_var = np.mean([t.scatter[0] for t in trials], axis=0)
    tau_var = np.mean([t.scatter[1] for t in trials], axis=0)
    window = np.mean([t.torque_window[1] - t.torque_window[0] for t in trials])
    jump_sensor = np.sqrt(dq_var * (1.0 / PRE_SAMPLES + 1.0 / (2 * POST_HALF_WIDTH + 1)))
    torque_sensor = np.sqrt(tau_var / max(window, 1.0))
    forced = [t for t in trials if t.impulse is not None]
    impulse = np.zeros(3)
    duration = 0.0
    if forced:
        rms = np.sqrt(np.mean([np.sum(t.impulse**2) for t in forced]))
        impulse = largest("impulse", IMPULSE_FLOOR_SHARE * rms * np.ones(3), repeat_std(forced, lambda t: t.impulse))
        periods = [t.force_period for t in forced if t.force_period]
        floor = DURATION_FLOOR_SAMPLES * min(periods, default=0.0)
        duration = float(largest("duration", floor, repeat_std(forced, lambda t: t.duration)).max())
    return BlockNoise(
        jump=largest("jump", jump_sensor, repeat_std(trials, lambda t: t.reference)),
        torque=largest("torque", REPLAY_TORQUE_FACTOR * torque_sensor, repeat_std(trials, lambda t: t.torque)),
        impulse=impulse,
        duration=duration,
        trace=largest("trace", np.sqrt(np.concatenate([dq_var, tau_var]) * (1.0 + 1.0 / PRE_SAMPLES))),
    )


def trace_std(trace: np.ndarray, sensor: np.ndarray) -> np.ndarray:
    """The noise std of each sample of a velocity trace (samples x joints): the sensor term
    ``sensor`` (per joint) and the replay's timing term, ``REPLAY_TIMING_SAMPLES`` times the
    trace's slope per sample (central differences; the trace starts from 0, the pre-impact
    mean), combined in quadrature."""
    padded = np.vstack([np.zeros((1, trace.shape[1])), trace, trace[-1:]])
    slope = 0.5 * (padded[2:] - padded[:-2])
    return np.sqrt(sensor**2 + (REPLAY_TIMING_SAMPLES * slope) ** 2)


def fits_noise(fit: dict) -> bool:
    """Whether every block of a fit (block -> normalised residual) is within ``FIT_LIMIT`` and
    its worst channel (``worst_channel``, when the fit has one) within ``CHANNEL_LIMIT``: a
    fault in one joint must not hide in a block's mean over all of them."""
    return all(fit[b] <= FIT_LIMIT for b in BLOCKS if b in fit) and not channel_misfits(fit)


def channel_misfits(fit: dict) -> bool:
    """Whether the worst channel of a fit (``fitting.fit_report``) is beyond ``CHANNEL_LIMIT``."""
    return fit.get("worst_channel", {}).get("value", 0.0) > CHANNEL_LIMIT


def misfit_blocks(fit: dict) -> list[str]:
    """The blocks of a fit (``fitting.fit_report``) above ``FIT_LIMIT``, worst first."""
    return sorted((b for b in BLOCKS if fit.get(b, 0.0) > FIT_LIMIT), key=lambda b: -fit[b])


def quadratic_mean(errors) -> float:
    """sqrt(mean(e^2)): the overall normalised residual of per-trial normalised residuals."""
    errors = np.asarray(errors, float)
    return float(np.sqrt(np.mean(errors**2))) if errors.size else 0.0


def outlier_trials(residuals) -> list[int]:
    """Indices of the trials that stand out: a normalised residual (``fitting.trial_errors``)
    above ``FIT_LIMIT`` (the trial misfits) and above the others': above ``OUTLIER_FACTOR`` times
    the median of all trials' residuals, or ``OUTLIER_SPREADS`` robust standard deviations
    (1.4826 times the median absolute deviation) above that median (a trial apart from the others
    when every trial misfits alike). Something happened in that trial alone. Worst first."""
    residuals = np.asarray(residuals, float)
    if residuals.size < 2:
        return []
    median = float(np.median(residuals))
    spread = MAD_TO_STD * float(np.median(np.abs(residuals - median)))
    limit = max(FIT_LIMIT, min(OUTLIER_FACTOR * median, median + OUTLIER_SPREADS * spread))
    return sorted(np.flatnonzero(residuals > limit).tolist(), key=lambda k: -residuals[k])
