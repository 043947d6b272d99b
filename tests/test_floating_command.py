"""The compiled kernels of a floating base's command (``floating_command``): equal to their
plain-numpy twins; the controller's G1 command is dq + ddq dt and q (+) (dq + dq_cmd) dt / 2
within the joints' limits."""

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.qp.command import command_limits
from impactqp.controller.qp.floating_command import floating_velocity_command, joint_positions_within

from conftest import g1_model
from reference.floating_command import reference_joint_positions_within, reference_velocity_command


def g1_limits():
    g1 = g1_model()
    return command_limits(g1, g1.ddq_max, g1.dddq_max * 1e-3)


@settings(max_examples=60, deadline=None)
@given(
    dq=arrays(float, 35, elements=st.floats(-30, 30)),
    ddq=arrays(float, 35, elements=st.floats(-3e4, 3e4)),
    dt=st.sampled_from([1e-3, 2e-3, 1e-2]),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_velocity_command_is_its_numpy_twin(dq, ddq, dt, seed):
    """dq_cmd and the half step bit for bit; the predicted jump A dq_cmd and post-impact velocity
    dq_cmd + A dq_cmd of a random jump matrix to rounding."""
    jump_matrix = np.random.default_rng(seed).normal(size=(35, 35))
    out = np.full((4, 35), np.nan)
    clipped = floating_velocity_command(dq, ddq, dt, g1_limits(), jump_matrix, out)
    dq_cmd, half_step, jump, expected = reference_velocity_command(dq, ddq, dt, g1_limits(), jump_matrix)
    assert clipped == expected
    np.testing.assert_array_equal(out[0], dq_cmd)
    np.testing.assert_array_equal(out[1], half_step)
    scale = np.abs(jump_matrix) @ np.abs(dq_cmd)
    np.testing.assert_array_less(np.abs(out[2] - jump), 1e-13 * (1.0 + scale))
    np.testing.assert_array_less(np.abs(out[3] - (dq_cmd + out[2])), 1e-13 * (1.0 + np.abs(dq_cmd + out[2])))


@settings(max_examples=60, deadline=None)
@given(joints=arrays(float, 29, elements=st.floats(-4, 4)))
def test_the_joint_positions_within_their_limits_are_the_numpy_twins(joints):
    g1 = g1_model()
    q = np.concatenate([pin.neutral(g1.model)[:7], joints])
    expected = reference_joint_positions_within(q, g1_limits())
    joint_positions_within(q, g1_limits())
    np.testing.assert_array_equal(q, expected)
    assert np.all(q[7:] >= g1.q_min) and np.all(q[7:] <= g1.q_max)
