"""The noise of the compared signals read from the data (sim/diagnosis/noise.py)."""

import json
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.dataset import read_header
from impactqp.controller.measured.impact import PRE_SAMPLES
from impactqp.sim.causes import ArmatureCause, JointDampingCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.noise import (
    BLOCKS,
    CHANNEL_LIMIT,
    FIT_LIMIT,
    REPLAY_TIMING_SAMPLES,
    fits_noise,
    misfit_blocks,
    outlier_trials,
    quantisation_step,
    repeat_std,
    sample_variance,
    trace_std,
)
from impactqp.sim.diagnosis.trials import load_trials
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(1e-3, 1.0), st.floats(0.0, 0.25), st.floats(0.5, 5.0))
def test_the_scatter_of_a_smooth_signal_recovers_its_white_noise(seed, sigma, curvature, frequency):
    """A smooth motion (sampled at 1 kHz) plus white noise: the second-difference estimate
    recovers the noise std within 15 % (10,000 samples: the estimate's own relative scatter is
    about 1.4 %, so 15 % is 10 of its standard deviations; with 1000 it was 4.5 %) while the motion's own second difference
    stays below ``curvature`` sigma (a quarter at most; the noise's is sqrt(6) sigma). A motion
    that curves as much as the noise is indistinguishable from it at one sample."""
    dt = 1e-3
    amplitude = curvature * sigma / (2 * np.pi * frequency * dt) ** 2  # |second difference| <= curvature sigma
    rng = np.random.default_rng(seed)
    t = np.arange(10_000) * dt
    smooth = amplitude * np.sin(2 * np.pi * frequency * t)[:, None] + np.array([[0.1, -0.3]]) * t[:, None]
    samples = smooth + rng.normal(0.0, sigma, (len(t), 2))
    assert np.all(quantisation_step(samples) == 0.0)  # white noise on a smooth motion: no common step
    np.testing.assert_allclose(np.sqrt(sample_variance(samples, quantisation_step(samples))), sigma, rtol=0.15)


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.floats(1e-4, 1e-1), st.floats(0.0, 0.1), st.floats(0.5, 5.0))
def test_a_quantised_signal_has_at_least_its_rounding_noise(seed, step, noise_share, frequency):
    """An encoder-like signal: a slow motion with noise far below the step (``noise_share`` of
    it), rounded to the step. Most second differences are 0, yet the noise read back is the
    rounding's, step / sqrt 12, at least, and the step is read from the data."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) * 1e-3
    smooth = 3.0 * step * np.sin(2 * np.pi * frequency * t)[:, None] + np.array([[3.3, -7.1]]) * step
    samples = step * np.round((smooth + rng.normal(0.0, noise_share * step, smooth.shape)) / step)
    np.testing.assert_allclose(quantisation_step(samples), step, rtol=1e-9)
    sigma = np.sqrt(sample_variance(samples, quantisation_step(samples)))
    assert np.all(sigma >= step / np.sqrt(12) * (1 - 1e-9)) and np.all(sigma <= step)


@settings(max_examples=30)
@given(st.integers(0, 2**32 - 1), st.integers(3, 40), st.floats(1e-4, 1e-1))
def test_a_mostly_flat_signal_does_not_read_noise_free(seed, jumps, size):
    """A signal flat but for a few steps of random size (no common step, so no rounding floor):
    its median |second difference| is 0, yet the noise read is the second differences' mean
    square over 6, never 0 (before: 0, the block noise then fell to its 1e-5 floor)."""
    rng = np.random.default_rng(seed)
    samples = np.zeros((1000, 1))
    for at in rng.choice(np.arange(1, 1000), jumps, replace=False):
        samples[at:] += rng.uniform(0.5, 1.0) * size
    second = np.diff(samples[:, 0], 2)
    assert np.median(np.abs(second)) == 0.0
    np.testing.assert_allclose(sample_variance(samples, np.zeros(1)), np.mean(second**2) / 6.0, rtol=1e-12)


def standing_out(residuals) -> float:
    """The residual above which a trial that misfits stands out: twice the median of all, or
    4 robust standard deviations (1.4826 median absolute deviation) above it, the lower."""
    median = np.median(residuals)
    return min(2 * median, median + 4 * 1.4826 * np.median(np.abs(np.array(residuals) - median)))


@given(st.lists(st.floats(0.0, FIT_LIMIT), min_size=1, max_size=20), st.floats(1.0, 100.0, exclude_min=True))
def test_a_trial_stands_out_when_it_misfits_and_is_far_above_the_others(residuals, scale):
    """Outliers are above the fit limit and far above the others (``standing_out``); a trial far
    above well-fitting trials (more than twice the fit limit: the median of the well-fitting ones
    may sit at the limit itself) is the only one named; one trial alone never stands out."""
    assert outlier_trials(residuals[:1]) == []
    assert outlier_trials(residuals) == []  # all within the fit limit
    worst = 2 * FIT_LIMIT * scale
    assert outlier_trials(residuals + [worst]) == ([len(residuals)] if worst > standing_out(residuals + [worst]) else [])
    if len(residuals) >= 3:  # the median and its deviation are the well-fitting trials'
        assert outlier_trials(residuals + [worst]) == [len(residuals)]


@settings(max_examples=50)
@given(st.integers(0, 2**32 - 1), st.integers(5, 30), st.floats(FIT_LIMIT, 20.0), st.floats(1e-3, 0.2), st.floats(15.0, 100.0))
def test_a_trial_apart_from_trials_that_all_misfit_stands_out(seed, n, level, spread, distance):
    """Every trial misfits alike (a model that misses something everywhere: residuals ``level``
    within +- ``spread``) and one lies ``distance`` spreads above them (beyond 4 robust standard
    deviations: their absolute deviations are at most 2 spreads): it is named first, and every
    trial above ``standing_out`` is named, worst first (before: only above twice the median, so
    a trial at 10 against 8 for every other was absorbed)."""
    rng = np.random.default_rng(seed)
    residuals = list(level + spread * rng.uniform(-1.0, 1.0, n))
    at = int(rng.integers(0, n + 1))
    residuals.insert(at, level + spread * distance)
    assert outlier_trials(residuals)[0] == at
    assert outlier_trials([8.0 + 0.01 * k for k in range(10)] + [10.0]) == [10]
    expected = [k for k, r in sorted(enumerate(residuals), key=lambda x: -x[1]) if r > max(FIT_LIMIT, standing_out(residuals))]
    assert outlier_trials(residuals) == expected


@given(st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), min_size=1, max_size=5))
def test_repeats_pool_their_within_condition_scatter(pairs):
    """Two repeats a, b per condition: pooled variance mean((a - b)^2 / 2); no repeat, no estimate."""
    trials = [SimpleNamespace(posture=f"p{k}", reference_speed=0.1, tangential_speed=0.0, x=v)
              for k, pair in enumerate(pairs) for v in pair]
    expected = np.sqrt(np.mean([(a - b) ** 2 / 2 for a, b in pairs]))
    assert repeat_std(trials, lambda t: t.x)[0] == pytest.approx(expected, abs=1e-9)
    assert repeat_std(trials[::2], lambda t: t.x) is None


@given(st.dictionaries(st.sampled_from(list(BLOCKS)), st.floats(0.0, 10.0), min_size=1))
def test_a_fit_fits_the_noise_unless_a_block_exceeds_the_limit_worst_named_first(fit):
    worst = misfit_blocks(fit)
    assert fits_noise(fit) == (not worst) == all(v <= FIT_LIMIT for v in fit.values())
    assert [fit[b] for b in worst] == sorted((v for v in fit.values() if v > FIT_LIMIT), reverse=True)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 12), st.floats(-1.0, 1.0))
def test_a_trace_sample_adds_the_replay_timing_times_its_slope_to_the_sensor_noise(seed, onset, slope):
    """Flat before ``onset``, a ramp after it: flat samples keep the sensor std, ramp samples
    (away from its ends) add REPLAY_TIMING_SAMPLES x slope in quadrature; never below the sensor."""
    rng = np.random.default_rng(seed)
    sensor = rng.uniform(1e-4, 1e-2, JOINTS)
    steps = np.maximum(np.arange(16) - onset, 0.0)
    trace = np.outer(steps, slope * rng.uniform(0.5, 1.0, JOINTS))
    std = trace_std(trace, sensor)
    assert std.shape == trace.shape and np.all(std >= sensor)
    np.testing.assert_allclose(std[: onset - 1], np.broadcast_to(sensor, std[: onset - 1].shape))
    ramp = np.sqrt(sensor**2 + (REPLAY_TIMING_SAMPLES * trace[-1] / max(15 - onset, 1)) ** 2)
    np.testing.assert_allclose(std[onset + 1 : 15], np.broadcast_to(ramp, std[onset + 1 : 15].shape), rtol=1e-9)


def test_the_noise_of_a_generated_dataset_is_read_back(tmp_path):
    """The generator's noise stds on dq and tau are recovered from the logs before the impact
    (within 25 % per joint), and the block noise of a jump follows from the dq noise."""
    request = DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.15], repeats=2, noise_dq=0.01, noise_tau=0.2, seed=5)
    generate_dataset(tmp_path, request)
    trials, _, _ = load_trials(tmp_path)
    dq = np.sqrt(np.mean([t.scatter[0] for t in trials], axis=0))
    tau = np.sqrt(np.mean([t.scatter[1] for t in trials], axis=0))
    np.testing.assert_allclose(dq, request.noise_dq, rtol=0.25)
    np.testing.assert_allclose(tau, request.noise_tau, rtol=0.25)
    assert np.all(trials[0].noise.jump >= 0.75 * request.noise_dq * np.sqrt(2 / 3))
    # a trace sample is one dq or tau sample minus the pre-impact mean
    scatter = np.concatenate([np.mean([t.scatter[k] for t in trials], axis=0) for k in (0, 1)])
    np.testing.assert_allclose(trials[0].noise.trace, np.sqrt(scatter * (1 + 1 / PRE_SAMPLES)), rtol=1e-12)


def shift_torque(directory, joint: int, offset: float) -> None:
    """Add ``offset`` (N m) to the logged torque of ``joint`` in every trial of a dataset."""
    for path in directory.glob("t????.csv"):
        header = path.read_text().splitlines()[0]
        table = np.loadtxt(path, delimiter=",", skiprows=1)
        table[:, header.split(",").index(f"tau{joint + 1}")] += offset
        np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")


def test_a_torque_offset_outside_the_candidates_is_a_named_misfit_not_an_explanation(tmp_path):
    """A torque sensor bias on one joint, which no plant cause makes: the jumps are untouched,
    the torque block misfits, nothing is explained and the message names the torque."""
    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.18], repeats=2, seed=3))
    shift_torque(tmp_path, 1, 1.5)
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS), JointDampingCause(JOINTS)]).summary()
    assert not result["explained"] and result["causes"] == []
    assert result["nominal_fit"]["torque"] > FIT_LIMIT >= result["nominal_fit"]["jump"]
    assert not result["fit"]["fits_noise"] and result["fit"]["torque"] > FIT_LIMIT
    assert "the torque residual is" in result["message"] and "as good as" not in result["message"]


def test_a_quantised_low_noise_dataset_of_the_nominal_plant_fits_the_nominal(tmp_path):
    """Real encoders: dq quantised to 0.004 rad/s with little noise (most second differences 0).
    The nominal plant made the data, so the nominal simulation fits them within the noise and
    nothing is refused as a misfit (before, the noise fell to its floor: 56 noise units)."""
    request = DatasetRequest(plant=PlantParameters(sensor_velocity_step=(0.004,) * JOINTS), postures=["elbow_up"],
                             speeds=[0.1, 0.18], repeats=2, noise_dq=0.0003, seed=4)
    generate_dataset(tmp_path, request)
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS)]).summary()
    assert result["nominal_fit"]["fits_noise"], result["nominal_fit"]
    assert not result["explained"] and result["message"].startswith("No candidate cause is needed"), result["message"]


def test_a_quantised_low_noise_dataset_of_a_plant_the_causes_model_is_explained(tmp_path):
    """The issue's case, small: a plant with rotor inertia, dq quantised to 0.004 rad/s with
    0.0003 rad/s of noise, the manifest declaring that step. The armature cause models the plant,
    so it is named, its interval holds the truth, and the fit is within the noise: no "times the
    noise ... mean nothing" refusal."""
    armature = (0.3,) * 4 + (0.15,) * 3
    plant = PlantParameters(armature=armature, sensor_velocity_step=(0.004,) * JOINTS)
    request = DatasetRequest(plant=plant, postures=["elbow_up"], speeds=[0.1, 0.18], repeats=2, noise_dq=0.0003, seed=4)
    generate_dataset(tmp_path, request)
    assert read_header(tmp_path).encoder_step == (0.004,) * JOINTS
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS)]).summary()
    assert result["explained"] and result["causes"] == ["armature"], result["message"]
    assert result["fit"]["fits_noise"] and "mean nothing" not in result["message"], result["message"]
    for row, truth in zip(result["parameter_intervals"], (0.3, 0.15)):
        low, high = row["interval"]
        assert (low is None or low <= truth) and (high is None or truth <= high), row


def test_a_declared_encoder_step_floors_the_noise_where_the_data_cannot_show_it(tmp_path):
    """A manifest's encoder_step is the step of dq even when the logged values do not show it
    (here: a step ten times the one they were rounded to): the jump noise is at least the
    rounding's through the jump's means, step / sqrt 12 sqrt(1/3 + 1/3)."""
    plant = PlantParameters(sensor_velocity_step=(0.004,) * JOINTS)
    generate_dataset(tmp_path, DatasetRequest(plant=plant, postures=["elbow_up"], speeds=[0.1, 0.18], noise_dq=0.0003, seed=4))
    manifest = json.loads((tmp_path / "dataset.json").read_text())
    read = load_trials(tmp_path)[0][0].noise.jump
    manifest["encoder_step"] = [0.04] * JOINTS
    (tmp_path / "dataset.json").write_text(json.dumps(manifest))
    declared = load_trials(tmp_path)[0][0].noise.jump
    assert np.all(read < 0.04 / np.sqrt(12) * np.sqrt(2 / 3))
    np.testing.assert_allclose(declared, 0.04 / np.sqrt(12) * np.sqrt(2 / 3), rtol=1e-9)


def delay_joint_velocity(directory, joint: int, samples: int) -> None:
    """Log the velocity of ``joint`` ``samples`` samples late in every trial of a dataset (the
    first sample held), as a faulty encoder channel would."""
    for path in directory.glob("t????.csv"):
        header = path.read_text().splitlines()[0]
        table = np.loadtxt(path, delimiter=",", skiprows=1)
        column = header.split(",").index(f"dq{joint + 1}")
        table[samples:, column] = table[:-samples, column].copy()
        table[:samples, column] = table[0, column]
        np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")


def test_a_fault_in_one_joints_channel_is_not_averaged_away(tmp_path):
    """Joint 4's velocity logged 3 samples late: its own channel misfits by far while the trace
    block, a mean over every joint's channels, stays near the limit. The fit is refused and the
    message names the channel, not a block."""
    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up", "elbow_left"], speeds=[0.1, 0.18], seed=6))
    delay_joint_velocity(tmp_path, 3, 3)
    result = diagnose(tmp_path, causes=[ArmatureCause(JOINTS)]).summary()
    channel = result["fit"]["worst_channel"]
    assert channel["channel"] in ("joint 4", "joint 4 velocity") and channel["value"] > CHANNEL_LIMIT, result["fit"]
    assert not result["explained"] and not result["fit"]["fits_noise"]
    assert "residual of joint 4" in result["message"], result["message"]
