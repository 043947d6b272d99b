"""What faulty sensors make of a log (sim/sensor.py)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.sim.plant import PlantParameterError, PlantParameters
from impactqp.sim.sensor import apply_sensor, delayed, low_pass, quantised_velocity

rows = st.integers(3, 40)


def log_of(seed: int, n: int) -> TrialLog:
    rng = np.random.default_rng(seed)
    return TrialLog(np.arange(n) * 1e-3, rng.normal(size=(n, JOINTS)), rng.normal(size=(n, JOINTS)), rng.normal(size=(n, JOINTS)),
                    rng.normal(size=(n, JOINTS)))


@given(st.integers(0, 2**32 - 1), rows, st.integers(0, 5))
def test_a_whole_sample_delay_shifts_the_rows_holding_the_first(seed, n, d):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    y = delayed(x, float(d))
    np.testing.assert_array_equal(y[d:], x[: n - d] if d < n else x[:0])
    np.testing.assert_array_equal(y[: min(d, n)], np.repeat(x[:1], min(d, n), axis=0))


@given(st.integers(0, 2**32 - 1), rows, st.floats(0.0, 5.0))
def test_a_fractional_delay_lies_between_the_whole_sample_ones(seed, n, d):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    y, a, b = delayed(x, d), delayed(x, np.floor(d)), delayed(x, np.floor(d) + 1)
    assert np.all(y >= np.minimum(a, b) - 1e-12) and np.all(y <= np.maximum(a, b) + 1e-12)


@given(st.floats(1e-4, 0.1), st.floats(-5, 5))
def test_the_filter_passes_a_constant_and_lags_a_step(time_constant, level):
    x = np.full((50, 2), level)
    np.testing.assert_allclose(low_pass(x, time_constant, 1e-3), x, atol=1e-12)
    step = np.vstack([np.zeros((1, 2)), np.ones((49, 2))])
    y = low_pass(step, time_constant, 1e-3)
    a = 1e-3 / (time_constant + 1e-3)
    np.testing.assert_allclose(y[1:, 0], 1 - (1 - a) ** np.arange(1, 50))


@given(st.integers(0, 2**32 - 1), rows, st.floats(0.5, 2.0), st.lists(st.floats(-20, 20), min_size=JOINTS, max_size=JOINTS))
def test_scale_and_offset_act_on_dq_and_tau_only(seed, n, scale, offset):
    log = log_of(seed, n)
    out = apply_sensor(log, PlantParameters(sensor_velocity_scale=scale, sensor_torque_offset=offset), 1e-3)
    np.testing.assert_allclose(out.dq, scale * log.dq)
    np.testing.assert_allclose(out.tau, log.tau + np.array(offset))
    np.testing.assert_array_equal(out.q, log.q)
    assert apply_sensor(log, PlantParameters(), 1e-3) is log


@given(st.integers(0, 2**32 - 1), rows, st.floats(0.5, 2.0), st.lists(st.floats(0.5, 2.0), min_size=JOINTS, max_size=JOINTS))
def test_the_joint_scales_multiply_the_global_one_per_joint(seed, n, scale, joints):
    log = log_of(seed, n)
    plant = PlantParameters(sensor_velocity_scale=scale, sensor_joint_velocity_scale=joints)
    np.testing.assert_allclose(apply_sensor(log, plant, 1e-3).dq, scale * np.array(joints) * log.dq)
    assert plant.physical() == PlantParameters()


@pytest.mark.parametrize(
    "key, value",
    [("sensor_delay", -1.0), ("sensor_delay", 51.0), ("sensor_velocity_scale", 0.4), ("sensor_velocity_filter", 0.2),
     ("sensor_torque_offset", [21.0] + [0.0] * 6), ("sensor_joint_velocity_scale", [1.0] * 6 + [2.5]),
     ("sensor_velocity_step", [0.0] * 6 + [0.2]), ("sensor_velocity_step", [-0.001] * 7)],
)
def test_sensor_keys_outside_their_physical_range_are_refused(key, value):
    with pytest.raises(PlantParameterError, match=key):
        PlantParameters(**{key: value})


@given(st.integers(0, 2**32 - 1), rows, st.lists(st.sampled_from([0.0, 1e-3, 0.004, 0.05]), min_size=JOINTS, max_size=JOINTS))
def test_an_encoder_rounds_each_joints_velocity_to_its_step_and_nothing_else(seed, n, steps):
    """Each joint's dq becomes the multiple of its step nearest to it (within half a step); a
    joint of step 0 is untouched; the step is a measurement's, so the replay's sensor
    (``apply_sensor``) and the simulated physics (``physical``) leave it out."""
    log = log_of(seed, n)
    plant = PlantParameters(sensor_velocity_step=steps)
    dq = quantised_velocity(log.dq, plant, JOINTS)
    for j, step in enumerate(steps):
        if step == 0.0:
            np.testing.assert_array_equal(dq[:, j], log.dq[:, j])
        else:
            np.testing.assert_allclose(dq[:, j] / step, np.round(dq[:, j] / step), atol=1e-9)
            assert np.all(np.abs(dq[:, j] - log.dq[:, j]) <= step / 2 * (1 + 1e-12))
    assert apply_sensor(log, plant, 1e-3) is log and plant.physical() == PlantParameters()
    assert quantised_velocity(log.dq, PlantParameters(), JOINTS) is log.dq
