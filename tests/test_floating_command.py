"""The compiled kernels of a floating base's command (``floating_command``): equal to their
plain-numpy twins; the controller's G1 command is dq + ddq dt and q (+) (dq + dq_cmd) dt / 2
within the joints' limits."""

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.qp.command import command_limits
from impactqp.controller.qp.floating_command import floating_velocity_command, held_brake, joint_positions_within

from conftest import g1_model
from whole_body_states import stance
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


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(["parallel", "wide", "staggered"]),
    seed=st.integers(0, 2**32 - 1),
    overshoot=st.floats(0.0, 2.0),
)
def test_the_held_brake_keeps_the_held_contacts_still_at_the_clipped_joint_rates(name, seed, overshoot):
    """Whatever the measured velocity (joints up to 3x past their limits, a base twist of up to
    10 m/s or rad/s that the feet do not allow), the brake's dq_cmd is finite, its joints within
    +-dq_max, its base twist the least-squares one of Jf_base v_base = -Jf_joints dq_joints (the
    normal equations Jf_base^T Jf dq_cmd = 0), and dq_cmd = dq + ddq dt."""
    g1 = g1_model()
    rng = np.random.default_rng(seed)
    dq = np.concatenate([10.0 * rng.uniform(-1, 1, g1.base_nv), (1.0 + overshoot) * g1.dq_max * rng.uniform(-1, 1, g1.n_joints)])
    terms = g1.terms(stance(name), dq)
    dt = 1e-3
    ddq, dq_cmd, q_cmd = held_brake(g1, terms, rng.normal(size=g1.nv), dt, g1_limits())
    assert np.all(np.isfinite(dq_cmd)) and np.all(np.isfinite(q_cmd))
    assert np.all(np.abs(dq_cmd[g1.base_nv:]) <= g1.dq_max)
    Jf = terms.held_jacobian
    residual = Jf[:, :g1.base_nv].T @ (Jf @ dq_cmd)
    assert np.abs(residual).max() <= 1e-9 * (1.0 + np.abs(Jf).max() ** 2 * np.abs(dq_cmd).max())
    np.testing.assert_allclose(dq_cmd, terms.dq + ddq * dt, rtol=0, atol=1e-9 * (1.0 + np.abs(dq_cmd).max()))
