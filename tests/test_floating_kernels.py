"""The compiled kernels of a floating base's per-cycle fill (``floating_kernels``): equal to their
plain-numpy twins, and the G1's per-cycle buffer equal to Pinocchio's own calls at random
states."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.floating_kernels import (
    NOT_UNIT_QUATERNION,
    QUATERNION_TOLERANCE,
    floating_frame_arrays,
    floating_frames_into,
    floating_state_status,
)
from impactqp.controller.model.model_terms import ACCEPTED, NOT_FINITE
from impactqp.controller.model.robot import InvalidStateError

from conftest import g1_model
from reference.floating_kernels import reference_floating_frames, reference_floating_state_status

LOCAL_WORLD_ALIGNED = pin.LOCAL_WORLD_ALIGNED


def random_state(seed: int, speed: float):
    """A random configuration of the G1 within its joints' limits (a random base placement) and
    a random velocity of scale ``speed``."""
    model = g1_model().model
    rng = np.random.default_rng(seed)
    np.random.seed(seed % 2**32)  # pinocchio's randomConfiguration draws from numpy's global generator
    lower, upper = np.clip(model.lowerPositionLimit, -3, 3), np.clip(model.upperPositionLimit, -3, 3)
    return pin.randomConfiguration(model, lower, upper), speed * rng.normal(size=model.nv)


def frame_terms(model, data, frame_id):
    """Pinocchio's own world-aligned Jacobian, classical acceleration and placement of a frame
    after the kinematics at ddq = 0."""
    pin.updateFramePlacement(model, data, frame_id)
    placement = data.oMf[frame_id]
    J6 = pin.getFrameJacobian(model, data, frame_id, LOCAL_WORLD_ALIGNED)
    drift = pin.getFrameClassicalAcceleration(model, data, frame_id, LOCAL_WORLD_ALIGNED).vector
    return J6, drift, placement.translation, placement.rotation


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), speed=st.sampled_from([0.0, 0.5, 3.0]))
def test_a_cycle_buffer_is_pinocchios_own_calls(seed, speed):
    g1 = g1_model()
    model, data = g1.model, g1.model.createData()
    q, v = random_state(seed, speed)
    terms = g1.update_terms(g1.empty_terms(), q, v)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.computeJointJacobians(model, data)
    expected = {"contact": frame_terms(model, data, g1.contact_frame_id)}
    for name, frame_id in g1.frame_ids.items():
        expected[name] = frame_terms(model, data, frame_id)
    held = [frame_terms(model, data, frame_id) for frame_id in g1.held_frame_ids]
    got = {"contact": (terms.J6, terms.dJ6_dq, terms.contact_point, terms.contact_rotation)}
    got |= {name: tuple(terms.frame(name)[k] for k in (2, 3, 0, 1)) for name in g1.frame_ids}
    for name, values in expected.items():
        for mine, theirs in zip(got[name], values):
            np.testing.assert_allclose(mine, theirs, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(terms.held_jacobian, np.vstack([J6 for J6, *_ in held]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(terms.held_drift, np.concatenate([d for _, d, *_ in held]), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(terms.J, terms.J6[:3])
    np.testing.assert_allclose(terms.com, pin.centerOfMass(model, data, q), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(terms.Jcom, pin.jacobianCenterOfMass(model, data, q), rtol=1e-12, atol=1e-12)
    pin.centerOfMass(model, data, q, v, np.zeros(model.nv))
    np.testing.assert_allclose(terms.dJcom_dq, data.acom[0], rtol=1e-12, atol=1e-12)
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(terms.M_inv @ M, np.eye(model.nv), atol=1e-8)
    pin.ccrba(model, data, q, v)
    assert terms.mass == pytest.approx(data.Ig.mass, rel=1e-14)
    np.testing.assert_allclose(terms.inertia_com, data.Ig.inertia, rtol=1e-12, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), speed=st.sampled_from([0.0, 1.0]))
def test_the_frames_kernel_is_its_numpy_twin(seed, speed):
    g1 = g1_model()
    model, data = g1.model, g1.data
    q, v = random_state(seed, speed)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.computeJointJacobians(model, data)
    joints, frames = g1._floating_frames
    out = floating_frame_arrays(len(joints), model.nv)
    for array in out:
        array[:] = np.nan  # every entry written
    floating_frames_into(data.J, joints, frames, out)
    for mine, theirs in zip(out, reference_floating_frames(data.J, joints, frames)):
        np.testing.assert_allclose(mine, theirs, rtol=1e-12, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    bad=st.sampled_from([None, np.nan, np.inf, 1e300]),
    entry=st.integers(0, 36 + 35 - 1),
    quaternion_scale=st.sampled_from([1.0, 1.0 + 0.5 * QUATERNION_TOLERANCE, 1.0 + 2 * QUATERNION_TOLERANCE, 0.5]),
)
def test_the_state_check_is_its_numpy_twin_and_copies_only_an_accepted_state(seed, bad, entry, quaternion_scale):
    g1 = g1_model()
    q, v = random_state(seed, 1.0)
    q[3:7] *= quaternion_scale
    if bad is not None:
        (q if entry < g1.nq else v)[entry % g1.nq if entry < g1.nq else entry - g1.nq] = bad
    q_out, v_out = np.zeros(g1.nq), np.zeros(g1.nv)
    status = floating_state_status(q, v, g1.base_nq, QUATERNION_TOLERANCE, q_out, v_out)
    assert status == reference_floating_state_status(q, v, g1.base_nq, QUATERNION_TOLERANCE)
    assert status in (ACCEPTED, NOT_FINITE, NOT_UNIT_QUATERNION)
    if status == ACCEPTED:
        np.testing.assert_array_equal(q_out, q)
        np.testing.assert_array_equal(v_out, v)
    else:
        assert not q_out.any() and not v_out.any()


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda q, v: q.__setitem__(9, np.nan), "q contains a non-finite value"),
        (lambda q, v: v.__setitem__(3, np.inf), "dq contains a non-finite value"),
        (lambda q, v: v.__setitem__(0, 1e300), "too large"),
        (lambda q, v: q.__setitem__(6, 2.0), "unit quaternion"),
    ],
)
def test_a_refused_state_leaves_the_buffer_as_it_was(change, message):
    g1 = g1_model()
    q, v = random_state(5, 1.0)
    terms = g1.update_terms(g1.empty_terms(), q, v)
    before = [np.array(x) for x in (terms.q, terms.dq, terms.J6, terms.held_jacobian, terms.com, terms.M_inv)]
    bad_q, bad_v = q.copy(), v.copy()
    change(bad_q, bad_v)
    with pytest.raises(InvalidStateError, match=message):
        g1.update_terms(terms, bad_q, bad_v)
    for old, new in zip(before, (terms.q, terms.dq, terms.J6, terms.held_jacobian, terms.com, terms.M_inv)):
        np.testing.assert_array_equal(old, new)
