"""The command filter never lets a velocity, acceleration or jerk step above the limits through."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.model.robot import ACCELERATION_LIMIT, JERK_LIMIT, VELOCITY_LIMIT
from impactqp.controller.runtime.command_filter import CommandFilter, acceleration_for

DT = 1e-3
TOL = 1e-9


def make_filter():
    return CommandFilter(DT, VELOCITY_LIMIT, ACCELERATION_LIMIT, JERK_LIMIT)


def assert_within_limits(commands, start):
    dq = np.vstack([start, start, commands])
    ddq = np.diff(dq, axis=0) / DT
    jerk = np.diff(ddq, axis=0) / DT
    assert np.all(np.abs(dq) <= VELOCITY_LIMIT * (1 + TOL))
    assert np.all(np.abs(ddq) <= ACCELERATION_LIMIT * (1 + TOL))
    assert np.all(np.abs(jerk) <= JERK_LIMIT * (1 + TOL))


requests = st.lists(
    st.one_of(
        st.lists(st.floats(-100.0, 100.0), min_size=JOINTS, max_size=JOINTS),
        st.just([float("nan")] * JOINTS),
        st.just([float("inf")] * JOINTS),
    ),
    min_size=1,
    max_size=120,
)


@settings(max_examples=150, deadline=None)
@given(requests, st.integers(1, 12))
def test_adversarial_requests_never_exceed_the_limits(sequence, hold):
    command_filter = make_filter()
    commands = [command_filter(np.array(request)) for request in sequence for _ in range(hold)]
    assert np.all(np.isfinite(commands))
    assert_within_limits(np.array(commands), np.zeros(JOINTS))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=JOINTS, max_size=JOINTS), requests)
def test_from_any_velocity_inside_the_limits_adversarial_requests_never_exceed_them(fraction, sequence):
    # the loop starts the filter at the measured velocity, with zero acceleration
    start = np.array(fraction) * VELOCITY_LIMIT
    command_filter = make_filter()
    command_filter.reset(start)
    commands = np.array([command_filter(np.array(request)) for request in sequence])
    assert_within_limits(commands, start)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=JOINTS, max_size=JOINTS))
def test_a_feasible_constant_request_is_reached_exactly_without_overshoot(fraction):
    target = np.array(fraction) * VELOCITY_LIMIT
    command_filter = make_filter()
    commands = np.array([command_filter(target) for _ in range(600)])
    assert np.allclose(commands[-1], target, atol=1e-12)
    # no overshoot: every joint moves monotonically towards its target
    assert np.all(np.diff(commands, axis=0) * np.sign(target) >= -1e-12)


def test_brake_from_full_speed_stops_within_the_limits():
    command_filter = make_filter()
    command_filter.reset(VELOCITY_LIMIT * 0.9)
    commands = np.array([command_filter.brake() for _ in range(400)])
    assert np.all(commands[-1] == 0.0)
    assert_within_limits(commands, VELOCITY_LIMIT * 0.9)


def test_velocity_change_and_its_inverse_agree():
    command_filter = make_filter()
    a = np.linspace(-3.0, 3.0, 61)[:, None] * ACCELERATION_LIMIT
    change = command_filter.velocity_change(a)
    inverse = np.array([[acceleration_for(c, s, DT) for c, s in zip(row, command_filter.jerk_step)] for row in change])
    assert np.allclose(inverse, a, rtol=1e-12, atol=1e-9)
    # g(a) = dt (a + (a - s) + ...) directly for one value
    s = JERK_LIMIT * DT
    a1 = 2.5 * s
    assert np.allclose(command_filter.velocity_change(a1), DT * (a1 + (a1 - s) + (a1 - 2 * s)))


class NumpyFilter:
    """The filter of the module docstring in numpy, all joints at once: the plain twin of the
    compiled ``filter_step``."""

    def __init__(self, start):
        self.dq, self.ddq = np.array(start, float), np.zeros(JOINTS)
        self.s = JERK_LIMIT * DT

    def inverse(self, change):
        budget = np.abs(change) / DT
        m = np.floor(0.5 * (np.sqrt(1.0 + 8.0 * budget / self.s) - 1.0))
        return np.sign(change) * (budget + 0.5 * self.s * m * (m + 1.0)) / (m + 1.0)

    def __call__(self, target):
        target = target if np.all(np.isfinite(target)) else np.zeros(JOINTS)
        dq, ddq, v = self.dq, self.ddq, VELOCITY_LIMIT
        lower = np.maximum(-ACCELERATION_LIMIT, ddq - self.s)
        upper = np.minimum(ACCELERATION_LIMIT, ddq + self.s)
        velocity_lower = np.maximum(-self.inverse(v + dq), (-v - dq) / DT)
        velocity_upper = np.minimum(self.inverse(v - dq), (v - dq) / DT)
        lower, upper = np.clip(velocity_lower, lower, upper), np.clip(velocity_upper, lower, upper)
        a = np.clip(self.inverse(target - dq), lower, upper)
        self.dq, self.ddq = dq + a * DT, a
        return self.dq.copy()


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=JOINTS, max_size=JOINTS), requests)
def test_the_compiled_filter_is_its_numpy_twin_bit_for_bit(fraction, sequence):
    start = np.array(fraction) * VELOCITY_LIMIT
    command_filter, twin = make_filter(), NumpyFilter(start)
    command_filter.reset(start)
    for request in sequence:
        np.testing.assert_array_equal(command_filter(np.array(request)), twin(np.array(request)))
        np.testing.assert_array_equal(command_filter.ddq, twin.ddq)


def test_a_request_of_the_wrong_size_is_a_request_to_stop():
    command_filter, twin = make_filter(), NumpyFilter(0.5 * VELOCITY_LIMIT)
    command_filter.reset(0.5 * VELOCITY_LIMIT)
    np.testing.assert_array_equal(command_filter(np.ones(JOINTS + 1)), twin(np.zeros(JOINTS)))


def test_a_read_only_or_strided_request_is_filtered_by_the_kernel_reset_loaded():
    """A request that is a read-only or a strided view (a command's array) is copied into the
    one array type that ``reset`` loaded the kernel for: no compile in a control period."""
    from impactqp.controller.runtime.command_filter import filter_step

    command_filter, twin = make_filter(), NumpyFilter(np.zeros(JOINTS))
    command_filter.reset(np.zeros(JOINTS))
    signatures = len(filter_step.signatures)
    read_only = np.full(JOINTS, 0.1)
    read_only.flags.writeable = False
    strided = np.full(2 * JOINTS, -0.1)[::2]
    for request in (read_only, strided):
        np.testing.assert_array_equal(command_filter(request), twin(np.array(request)))
    assert len(filter_step.signatures) == signatures
