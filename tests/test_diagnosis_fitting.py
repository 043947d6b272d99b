"""Residuals of a replay and the causes' fitted vectors (sim/diagnosis/fitting.py)."""

from dataclasses import replace

import numpy as np
import pytest
from diagnosis_checks import exact_features, synthetic_trial
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import ArmatureCause, FrictionCause, PayloadCause
from impactqp.sim.diagnosis.fitting import (
    FittedCauses,
    fit_report,
    jump_errors,
    residual_sizes,
    residuals,
    trial_errors,
)
from impactqp.sim.diagnosis.noise import CHANNEL_LIMIT, FIT_LIMIT, trace_std
from impactqp.sim.plant import PlantParameters


def trials_of(seed: int, forces: list[bool]):
    rng = np.random.default_rng(seed)
    return [synthetic_trial(rng, force=force) for force in forces]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.booleans(), min_size=1, max_size=6))
def test_a_replay_that_reproduces_the_trials_leaves_no_residual(seed, forces):
    trials = trials_of(seed, forces)
    features = [exact_features(t) for t in trials]
    r = residuals(features, trials)
    assert len(r) == sum(residual_sizes(trials))
    np.testing.assert_array_equal(r, 0.0)
    np.testing.assert_array_equal(jump_errors(features, trials), 0.0)
    np.testing.assert_array_equal(trial_errors(features, trials), 0.0)
    fit = fit_report(features, trials)
    assert fit["fits_noise"] and fit["jump"] == fit["torque"] == fit["trace"] == 0.0
    assert ("impulse" in fit) == ("duration" in fit) == any(forces)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.booleans(), min_size=1, max_size=6), st.floats(-1.0, 1.0))
def test_a_jump_offset_shows_in_the_jump_residuals_and_errors_only(seed, forces, offset):
    """Each trial's block starts with its jump residuals (one per joint): (jump error) / its noise std; the
    jump block alone misfits, by |offset| / noise in root mean square."""
    trials = trials_of(seed, forces)
    features = [replace(exact_features(t), jump=t.reference + offset) for t in trials]
    r = residuals(features, trials)
    starts = np.concatenate([[0], np.cumsum(residual_sizes(trials))[:-1]])
    jump_rows = np.concatenate([np.arange(s, s + JOINTS) for s in starts])
    np.testing.assert_allclose(r[jump_rows], np.concatenate([offset / t.noise.jump for t in trials]), rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(np.delete(r, jump_rows), 0.0)
    np.testing.assert_allclose(jump_errors(features, trials), abs(offset), rtol=1e-9, atol=1e-12)
    fit = fit_report(features, trials)
    expected = np.sqrt(np.mean(np.concatenate([(offset / t.noise.jump) ** 2 for t in trials])))
    assert fit["jump"] == pytest.approx(expected) and fit["torque"] == 0.0
    assert fit["fits_noise"] == (expected <= FIT_LIMIT)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.booleans(), min_size=1, max_size=6), st.floats(-1.0, 1.0))
def test_a_trace_offset_shows_in_the_trace_block_only(seed, forces, offset):
    """Each trial's residuals end with its velocity trace (samples x joints) over the trace noise; a
    trace that is off leaves the jump error (26) and every other block untouched."""
    trials = trials_of(seed, forces)
    features = [replace(exact_features(t), trace=t.reference_trace + offset) for t in trials]
    fit = fit_report(features, trials)
    expected = np.sqrt(np.mean(np.concatenate([np.ravel((offset / trace_std(t.reference_trace, t.noise.trace)) ** 2)
                                               for t in trials])))
    assert fit["trace"] == pytest.approx(expected)
    assert all(fit[b] == 0.0 for b in fit if b not in ("trace", "fits_noise", "worst_channel"))
    # the worst channel: one column of the trace (a joint's velocity or torque) over every trial and sample
    columns = np.concatenate([offset / trace_std(t.reference_trace, t.noise.trace) for t in trials])
    per_channel = np.sqrt(np.mean(columns**2, axis=0))
    if per_channel.max() > 1e-9:  # an offset far below the trace values cancels in (reference + offset) - reference
        assert fit["worst_channel"]["block"] == "trace"
    assert fit["worst_channel"]["value"] == pytest.approx(per_channel.max())
    assert fit["worst_channel"]["value"] >= fit["trace"] * (1 - 1e-12)  # a mean never exceeds its largest part
    assert fit["fits_noise"] == (expected <= FIT_LIMIT and per_channel.max() <= CHANNEL_LIMIT)
    np.testing.assert_array_equal(jump_errors(features, trials), 0.0)
    sizes = residual_sizes(trials)
    ends = np.cumsum(sizes)
    r = residuals(features, trials)
    for t, end in zip(trials, ends):
        np.testing.assert_allclose(r[end - t.reference_trace.size : end],
                                   (offset / trace_std(t.reference_trace, t.noise.trace)).ravel(), rtol=1e-9, atol=1e-9)


def test_a_replay_without_a_contact_counts_as_a_zero_impulse():
    (trial,) = trials_of(1, [True])
    missing = replace(exact_features(trial), impulse=None, duration=None)
    zero = replace(exact_features(trial), impulse=np.zeros(3), duration=0.0)
    np.testing.assert_array_equal(residuals([missing], [trial]), residuals([zero], [trial]))


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_fitted_causes_split_and_join_their_vectors_and_apply_in_order(seed):
    rng = np.random.default_rng(seed)
    model = FittedCauses()
    for cause in (ArmatureCause(JOINTS), PayloadCause(), FrictionCause()):
        lo, hi = cause.u_bounds()
        model = model.plus(cause, rng.uniform(lo, hi))
    u = model.vector()
    again = model.with_vector(u)
    assert [len(v) for v in again.u] == [2, 4, 1]
    np.testing.assert_array_equal(again.vector(), u)
    lo, hi = model.bounds()
    assert len(lo) == len(hi) == len(u) and np.all(lo <= u) and np.all(u <= hi)
    plant = PlantParameters()
    for cause, v in zip(model.causes, model.u):
        plant = cause.plant(plant, v)
    assert model.plant(PlantParameters()) == plant
    assert model.overrides() == {
        key: value for c, v in zip(model.causes, model.u) for key, value in c.overrides(c.to_theta(v)).items()
    }
