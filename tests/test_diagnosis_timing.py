"""One timing for every trial: the per-trial shift of the velocity trace against the replay and
Cochran's homogeneity test of the shifts (sim/diagnosis/timing.py)."""

from dataclasses import replace

import numpy as np
from diagnosis_checks import exact_features, synthetic_trial
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from conftest import JOINTS
from impactqp.sim.diagnosis.noise import BlockNoise
from impactqp.sim.diagnosis.timing import TIMING_LEVEL, shifted, timing_test, trial_shift
from impactqp.sim.diagnosis.trials import impact_trace
from impactqp.sim.scene import DEFAULT_TIMESTEP
from impactqp.sim.sensor import delayed

SAMPLES = 60
PRE = 30  # the pre-impact sample of the synthetic logs
START = PRE + 4  # the first sample of the velocities' rise: a measurement 3 samples early stays after PRE


def rise(rng: np.random.Generator, samples: int = SAMPLES) -> np.ndarray:
    """Joint velocities (samples x joints) flat until ``START``, then a smooth rise of a random
    size and time constant per joint: the shape of a jump."""
    k = np.arange(samples) - START
    size = rng.uniform(-0.3, 0.3, JOINTS)
    time_constant = rng.uniform(1.0, 4.0, JOINTS)
    return 0.1 + np.where(k[:, None] > 0, size * (1.0 - np.exp(-np.maximum(k, 0)[:, None] / time_constant)), 0.0)


def trial_with(rng: np.random.Generator, dq: np.ndarray, sigma: float = 1e-3):
    """A synthetic trial whose measured velocities are ``dq`` (its torques flat), its impact at
    ``PRE`` and every trace sample's sensor std ``sigma``."""
    trial = synthetic_trial(rng, samples=len(dq))
    noise = BlockNoise(trial.noise.jump, trial.noise.torque, trial.noise.impulse, trial.noise.duration,
                       np.full(2 * JOINTS, sigma))
    return replace(trial, dq_log=dq, tau_log=np.zeros_like(dq), jump_samples=(PRE, PRE + 4), noise=noise)


def lagging(rng: np.random.Generator, lags, sigma: float = 1e-3):
    """Trials whose measured velocities lag their replays' (``rise``) by ``lags`` samples, and
    those replays' features."""
    trials, features = [], []
    for lag in lags:
        true = rise(rng)
        trial = trial_with(rng, delayed(true, lag), sigma)
        trials.append(trial)
        features.append(replace(exact_features(trial), trace=impact_trace(true, trial.tau_log, PRE)))
    return trials, features


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-5.0, 5.0))
def test_a_trace_read_late_is_lined_up_at_its_delay(seed, lag):
    """The measured trace is the replayed one read ``lag`` samples late, exactly: the shift
    that lines them up is ``lag``, and its variance is the noise's part (the inverse of the
    weighted squared slopes) plus the timing's."""
    rng = np.random.default_rng(seed)
    replay = rise(rng)[PRE + 1:PRE + 17] - 0.1  # a trace: the samples after PRE minus the level before
    sigma = rng.uniform(1e-3, 1e-2, JOINTS)
    s, v = trial_shift(shifted(replay, lag), replay, sigma, 0.25)
    assert abs(s - lag) < 0.01
    slope = np.gradient(shifted(replay, s), axis=0)
    assert np.isclose(v, 1.0 / np.sum((slope / sigma) ** 2) + 0.25**2)


def test_a_replay_without_a_slope_has_no_shift():
    flat = np.zeros((16, JOINTS))
    assert trial_shift(flat, flat, np.ones(JOINTS), 0.25) == (0.0, float("inf"))


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-3.0, 3.0))
def test_one_timing_for_every_trial_holds_and_per_trial_delays_are_refused(seed, lag):
    """Every trial lagging its replay by the same ``lag`` (within a tenth of the replay's
    timing): one timing, whatever it is (a delay every trial shares is a cause's, not this
    test's). The same trials lagging by whole samples drawn per trial (0-4, at least two
    different): refused, and each trial's shift is its own lag."""
    rng = np.random.default_rng(seed)
    timing = DEFAULT_TIMESTEP / 1e-3  # the synthetic trials' control period: 1 ms
    trials, features = lagging(rng, lag + rng.normal(0.0, 0.1 * timing, 6))
    same = timing_test(features, trials)
    assert same["consistent"] and same["dof"] == 5
    assert np.allclose(same["shifts"], lag, atol=0.1)
    lags = rng.permutation([0, 4] + rng.integers(0, 5, 4).tolist())
    trials, features = lagging(rng, lags)
    apart = timing_test(features, trials)
    assert not apart["consistent"] and apart["p_value"] < TIMING_LEVEL
    assert np.allclose(apart["shifts"], lags, atol=0.05)


def test_the_statistic_is_chi_square_when_each_trial_is_off_by_the_replay_timing_alone():
    """Each trial's replay off by a normal draw of the replay's timing std (tau, one physics
    step) and no sensor noise: Q = sum (s_i - mean)^2 / v_i is chi-square on n - 1 degrees of
    freedom, so its mean over many datasets is n - 1 and a true null is refused about
    ``TIMING_LEVEL`` of the time (none of 150)."""
    rng = np.random.default_rng(3)
    statistics, refused = [], 0
    for _ in range(150):
        trials, features = lagging(rng, rng.normal(0.0, DEFAULT_TIMESTEP / 1e-3, 6), sigma=1e-6)
        result = timing_test(features, trials)
        statistics.append(result["statistic"])
        refused += not result["consistent"]
    assert abs(np.mean(statistics) - 5.0) < 4 * np.sqrt(2 * 5 / 150)  # chi2_5: mean 5, variance 10
    assert refused == 0
    assert abs(np.mean(np.array(statistics) > chi2.ppf(0.9, 5)) - 0.1) < 0.08


def test_fewer_than_two_trials_test_nothing():
    trials, features = lagging(np.random.default_rng(0), [2.0])
    result = timing_test(features, trials)
    assert result["consistent"] and result["dof"] == 0 and result["p_value"] == 1.0
