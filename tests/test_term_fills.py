"""The fills of an arm's model terms (controller/model/term_fills.py): a prediction's terms (one
world-frame CRBA pass, M, h and the drift on first read) and a controller's buffer refilled in
place equal a plain ``computeAllTerms``; refills give a new state's terms and refuse singular
states, leaving the buffer as it was; the refill's kernel (``model_terms.arm_cycle_terms``) is
its numpy twin."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import joint_positions
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.model_terms import reference_arm_cycle_terms
from test_robot import SINGULAR_Q

from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.model_terms import (
    ACCEPTED,
    ARM_STATE_EXTRA,
    NEAR_SINGULAR,
    arm_cycle_checks,
    arm_cycle_terms,
    arm_state_views,
    contact_jacobian_status,
)
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import InvalidStateError, SingularPostureError
from impactqp.controller.model.term_fills import SINGULAR_RATIO_SQUARED
from impactqp.controller.model.tool_postures import tool_posture
from impactqp.controller.model.validation import BadInputError


@settings(max_examples=30, deadline=None)
@given(q_a=joint_positions(), q_b=joint_positions())
def test_refilled_terms_equal_fresh_terms(robot, q_a, q_b):
    """update_terms rewrites a ModelTerms buffer into exactly what terms() computes, with a new
    stamp and the derived quantities (J+, cond M) of the new state, not the old one."""
    rng = np.random.default_rng(0)
    dq_a, dq_b = rng.uniform(-1, 1, robot.nv), rng.uniform(-1, 1, robot.nv)
    try:
        buffer = robot.terms(q_a, dq_a, check_limits=False)
        fresh = robot.terms(q_b, dq_b, check_limits=False)
    except SingularPostureError:
        return
    buffer.J_pinv, buffer.cond_M  # cache the derived quantities of state a
    stamp = buffer.stamp
    assert robot.update_terms(buffer, q_b, dq_b, check_limits=False) is buffer
    assert buffer.stamp != stamp
    for name in ("q", "dq", "M", "h", "J", "J6", "dJ6_dq", "JJt_inv", "contact_point", "contact_rotation",
                 "com", "inertia_com", "contact_terms", "arm_state", "locked_body"):
        np.testing.assert_allclose(getattr(buffer, name), getattr(fresh, name), rtol=1e-12, atol=1e-12)
    assert buffer.mass == fresh.mass
    np.testing.assert_allclose(buffer.J_pinv, np.linalg.pinv(fresh.J), atol=1e-9)
    assert buffer.cond_M == pytest.approx(np.linalg.cond(fresh.M))


def test_a_refill_copies_the_callers_state_into_the_buffer(robot):
    """A cycle buffer's q, dq and contact rotation are its own writable row-major arrays, the
    same at every refill, whatever the caller passed (read-only, strided): what the compiled
    kernels read, one signature each."""
    buffer = robot.empty_terms()
    arrays = (buffer.arm_state, buffer.q, buffer.dq, buffer.contact_rotation)
    q = np.repeat(tool_posture(robot, robot.description.default_posture).q, 2)[::2]  # a strided view
    dq = np.full(robot.nv, 0.1)
    q.flags.writeable = dq.flags.writeable = False
    robot.update_terms(buffer, q, dq)
    fresh = robot.terms(q, dq)
    assert all(now is before for now, before in zip((buffer.arm_state, buffer.q, buffer.dq, buffer.contact_rotation), arrays))
    for array in arrays:
        assert array.flags.writeable and array.flags.c_contiguous
    for name in ("q", "dq", "contact_rotation"):
        np.testing.assert_array_equal(getattr(buffer, name), getattr(fresh, name))


@settings(max_examples=20, deadline=None)
@given(q_a=joint_positions(), q_b=joint_positions())
def test_new_terms_keep_their_state_when_the_caller_reuses_its_arrays(robot, q_a, q_b):
    """The terms' q and dq are their own: M, h and M^-1, filled at their first read, are those
    of the state given, even when the caller has written another state into its arrays since."""
    q, dq = q_a.copy(), np.full(robot.nv, 0.2)
    try:
        terms, expected = robot.terms(q, dq), robot.terms(q_a.copy(), np.full(robot.nv, 0.2))
    except SingularPostureError:
        return
    q[:], dq[:] = q_b, -0.5
    assert not np.shares_memory(terms.q, q) and not np.shares_memory(terms.dq, dq)
    for name in ("M", "h", "M_inv"):
        np.testing.assert_array_equal(getattr(terms, name), getattr(expected, name))


@pytest.mark.parametrize("bad", [np.full(7, 0.1 + 0.1j), np.ones(7, dtype=bool), ["a"] * 7, [0.1] * 6 + [1j]])
def test_a_state_of_complex_numbers_booleans_or_text_is_refused_without_a_warning(robot, bad, recwarn):
    """Numpy would drop an imaginary part with a warning and read booleans as 0 and 1 radians."""
    q = np.resize(np.asarray(bad), robot.nq) if isinstance(bad, np.ndarray) else (bad * robot.nq)[:robot.nq]
    with pytest.raises(InvalidStateError, match="q must hold real numbers"):
        robot.terms(q)
    with pytest.raises(InvalidStateError, match="q must hold real numbers"):
        robot.update_terms(robot.empty_terms(), q, np.zeros(robot.nv))
    assert not recwarn.list


@settings(max_examples=50, deadline=None)
@given(q=joint_positions())
def test_closed_form_inverse_of_J_Jt(robot, q):
    """(J J^T)^-1 by the adjugate times J J^T is the identity."""
    try:
        terms = robot.terms(q, check_limits=False)
    except SingularPostureError:
        return
    np.testing.assert_allclose(terms.JJt_inv @ (terms.J @ terms.J.T), np.eye(3), atol=1e-8)


REFUSED_STATES = {
    "singular": (SINGULAR_Q, np.zeros(7), SingularPostureError, "singular"),
    "non-finite": (PANDA.postures["elbow_up"].q, np.array([0.0, np.nan, 0, 0, 0, 0, 0]), InvalidStateError, "non-finite"),
    "huge": (PANDA.postures["elbow_up"].q, np.array([0.0, 0, 1e300, 0, 0, 0, 0]), InvalidStateError, "too large"),
    "outside limits": (PANDA.q_max + 0.1, np.zeros(7), InvalidStateError, "outside the joint limits"),
}


@pytest.mark.parametrize("case", REFUSED_STATES)
def test_a_refused_state_leaves_the_buffer_as_it_was(robot, case):
    """A singular posture, a non-finite or huge entry, a joint outside its limits: the refill
    raises (naming why) and every field, those that view the buffer's Pinocchio data included,
    keeps the previous state's value."""
    q_bad, dq_bad, error, message = REFUSED_STATES[case]
    q, dq = PANDA.postures["elbow_up"].q, np.full(robot.nv, 0.2)
    names = ("q", "dq", "M", "h", "J6", "dJ6_dq", "JJt_inv", "com", "contact_point", "contact_rotation", "inertia_com",
             "contact_terms", "locked_body")
    for buffer in (robot.terms(q, dq), robot.update_terms(robot.empty_terms(), q, dq)):
        stamp, before = buffer.stamp, {name: np.copy(getattr(buffer, name)) for name in names}
        with pytest.raises(error, match=message):
            robot.update_terms(buffer, q_bad, dq_bad)
        assert buffer.stamp == stamp
        for name, value in before.items():
            np.testing.assert_array_equal(getattr(buffer, name), value, err_msg=name)
        np.testing.assert_allclose(buffer.M_inv @ buffer.M, np.eye(robot.nv), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(q=joint_positions(), dq=joint_positions(0.0))
def test_a_cycle_buffers_inverse_inertia_is_computeMinverses(robot, q, dq):
    """A refilled buffer's M^-1 (the Cholesky factor of its own M: ``pin.cholesky``) equals
    Pinocchio's ``computeMinverse`` at q (both triangles) to 1e-12 of its largest entry, and is
    the inverse of the buffer's M."""
    buffer = robot.update_terms(robot.empty_terms(), q, 0.1 * dq, check_limits=False)
    upper = pin.computeMinverse(robot.model, robot.model.createData(), q)
    expected = np.triu(upper) + np.triu(upper, 1).T
    np.testing.assert_allclose(buffer.M_inv, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(buffer.M_inv @ buffer.M, np.eye(robot.nv), atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(q=joint_positions(), dq=joint_positions(0.0))
def test_an_arms_terms_are_one_compute_all_terms(robot, q, dq):
    """Both fills (a prediction's ``terms``: one world-frame CRBA pass, M, h and the drift on
    first read; a controller's ``update_terms`` of a preallocated buffer, in place) equal a plain
    ``computeAllTerms`` on a fresh data (to 1e-12), hold no held contact, and compute M^-1, Jcom
    and its drift on first use (definitions checked)."""
    dq = 0.3 * (dq - robot.q_min) / (robot.q_max - robot.q_min) - 0.15
    for terms in (robot.terms(q, dq), robot.update_terms(robot.empty_terms(), q, dq)):
        check_one_compute_all_terms(robot, terms, q, dq)


def check_one_compute_all_terms(robot, terms, q, dq):
    model, data = robot.model, robot.model.createData()
    pin.computeAllTerms(model, data, q, dq)
    pin.updateFramePlacements(model, data)
    fid, world = robot.contact_frame_id, pin.LOCAL_WORLD_ALIGNED
    expected = {
        "M": data.M, "h": data.nle, "J6": pin.getFrameJacobian(model, data, fid, world),
        "dJ6_dq": pin.getFrameClassicalAcceleration(model, data, fid, world).vector,
        "contact_point": data.oMf[fid].translation, "contact_rotation": data.oMf[fid].rotation,
        "com": data.com[0], "inertia_com": data.Ig.inertia,
    }
    for name, value in expected.items():
        np.testing.assert_allclose(getattr(terms, name), value, rtol=0, atol=1e-12, err_msg=name)
    assert terms.mass == pytest.approx(data.Ig.mass, rel=1e-12)
    packed = np.concatenate([terms.J6.ravel(), terms.JJt_inv.ravel(), terms.contact_point])  # [J6, (J J^T)^-1, p]
    np.testing.assert_array_equal(terms.contact_terms, packed)
    assert terms.held_jacobian.shape == (0, robot.nv) and terms.held_drift.shape == (0,)
    np.testing.assert_allclose(terms.M_inv @ terms.M, np.eye(robot.nv), atol=1e-8)
    eps = 1e-6
    rate = (pin.centerOfMass(model, data, q + eps * dq) - pin.centerOfMass(model, data, q - eps * dq)) / (2 * eps)
    np.testing.assert_allclose(terms.Jcom @ dq, rate, atol=1e-8)
    Jcom_rate = (pin.jacobianCenterOfMass(model, data, q + eps * dq) - pin.jacobianCenterOfMass(model, data, q - eps * dq)) @ dq
    np.testing.assert_allclose(terms.dJcom_dq, Jcom_rate / (2 * eps), atol=1e-6)
    with pytest.raises(BadInputError, match="unknown frame"):
        terms.frame("torso")


@settings(max_examples=20, deadline=None)
@given(q=joint_positions(), dq=joint_positions(0.0), restitution=st.floats(0.0, 1.0))
def test_a_cycle_buffer_gives_the_jump_maps_of_a_predictions_terms(robot, q, dq, restitution):
    """The crb, gm and classical maps (A, P, G) of a controller's refilled buffer (its M^-1 from
    the Cholesky factor of its own M) equal those of a prediction's terms at the same state
    (M^-1 from ``computeMinverse``) to 1e-12 of their largest entry."""
    dq = 0.1 * dq
    try:
        prediction = robot.terms(q, dq, check_limits=False)
    except SingularPostureError:
        return
    buffer = robot.update_terms(robot.empty_terms(), q, dq, check_limits=False)
    normal = np.array([-1.0, 0.0, 0.0])
    for name in ("crb", "gm", "classical"):
        expected = jump_model(name).unit_matrices(prediction, normal, restitution)
        got = jump_model(name).unit_matrices(buffer, normal, restitution)
        for field in ("jump_matrix", "torque_matrix", "impulse_map"):
            reference = getattr(expected, field)
            np.testing.assert_allclose(
                getattr(got, field), reference, rtol=0, atol=1e-12 * np.abs(reference).max(), err_msg=f"{name} {field}"
            )


@settings(max_examples=40, deadline=None)
@given(q=joint_positions(), dq=joint_positions(0.0), scale=st.sampled_from([0.0, 0.3, np.nan, 1e300]), check=st.booleans())
def test_the_cycle_kernel_is_its_numpy_twin_and_pinocchios_frame_terms(robot, q, dq, scale, check):
    """``arm_cycle_terms`` (J6, (J J^T)^-1, p, its drift, dq, R and q, from the data's joint
    Jacobians and placement) gives its plain-numpy twin's status and arrays, and writes them only
    when it accepts the state; accepted, they are Pinocchio's frame Jacobian, the frame's
    classical acceleration and the inverse of J J^T."""
    model, data, fid = robot.model, robot.model.createData(), robot.contact_frame_id
    dq = scale * dq
    pin.computeAllTerms(model, data, q, np.nan_to_num(dq))
    pin.updateFramePlacement(model, data, fid)
    placement = data.oMf[fid]
    world, support = (data.J, data.dJ, placement.translation, placement.rotation), robot._contact_support
    unlimited = np.full(robot.nq, np.inf)
    limits = (robot.q_min, robot.q_max) if check else (-unlimited, unlimited)
    out = np.full(7 * robot.nv + robot.nq + ARM_STATE_EXTRA, 7.0)
    status = arm_cycle_terms(*world, q, dq, arm_cycle_checks(SINGULAR_RATIO_SQUARED, *limits, support), out)
    expected = reference_arm_cycle_terms((*world, support), (q, dq), (np.stack(limits), True, SINGULAR_RATIO_SQUARED))
    assert status == expected[0]
    if status != ACCEPTED:
        assert np.all(out == 7.0)
        return
    outputs = arm_state_views(out, robot.nv)  # J6, (J J^T)^-1, p, drift, dq, R, q
    for array, twin in zip(outputs, expected[1:]):  # (J J^T)^-1 grows near a singular posture: relative
        np.testing.assert_allclose(array, twin, rtol=0, atol=1e-12 * max(1.0, np.abs(twin).max()))
    assert not np.any(out == 7.0)  # every entry written
    world_aligned = pin.LOCAL_WORLD_ALIGNED
    np.testing.assert_allclose(outputs[0], pin.getFrameJacobian(model, data, fid, world_aligned), rtol=0, atol=1e-12)
    drift = pin.getFrameClassicalAcceleration(model, data, fid, world_aligned).vector
    np.testing.assert_allclose(outputs[3], drift, rtol=0, atol=1e-12)
    np.testing.assert_allclose(outputs[1] @ outputs[0][:3] @ outputs[0][:3].T, np.eye(3), atol=1e-8)


def test_a_contact_jacobian_of_zeros_is_singular(robot):
    """J = 0 (a contact no joint moves): det(J J^T) = 0 met the bound ratio^2 trace^3 = 0 and was
    accepted; it is near-singular for the kernel and singular for the exact test."""
    q, J = robot.description.postures["elbow_up"].q, np.zeros((3, robot.nv))
    status = contact_jacobian_status(J, q, robot.q_min, robot.q_max, True, SINGULAR_RATIO_SQUARED, np.empty((3, 3)))
    assert status == NEAR_SINGULAR
    with pytest.raises(SingularPostureError, match="singular contact Jacobian"):
        robot._refuse(J, q, np.zeros(robot.nv), status, True)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_floating_bases_held_jacobian_alone_is_its_terms(seed):
    """``held_jacobian(q)`` (the kinematics alone, a standing plant's every period) is
    ``terms(q).held_jacobian`` bit for bit, at random configurations of the G1 in any order, and
    Pinocchio's world-aligned frame Jacobians of the held contacts."""
    from conftest import g1_model

    g1 = g1_model()
    rng = np.random.default_rng(seed)
    model, data = g1.model, g1.model.createData()
    for _ in range(3):
        q = pin.neutral(model)
        q[:3] = rng.uniform(-1.0, 1.0, 3)
        q[3:7] = pin.Quaternion(*rng.normal(size=4)).normalized().coeffs()
        q[7:] = rng.uniform(model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        np.testing.assert_array_equal(g1.held_jacobian(q), g1.terms(q).held_jacobian)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        frames = [model.getFrameId(c.frame) for c in g1.description.held_contacts]
        expected = np.vstack([pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED) for f in frames])
        np.testing.assert_allclose(g1.held_jacobian(q), expected, rtol=0, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(arm_q=joint_positions(), seed=st.integers(0, 2**32 - 1))
def test_the_pinocchio_pass_alone_gives_what_a_refill_reads(robot, arm_q, seed):
    """``pinocchio_pass`` (what the bench's cycle floor times) runs every Pinocchio algorithm a
    refill reads: on a data of its own at a random state, its M^-1 (upper triangle, mirrored),
    centre of mass, its acceleration and Jacobian and the centroidal inertia are the G1's refilled
    terms' bit for bit; on the Panda, its ``computeAllTerms`` gives the refill's M and h."""
    from conftest import g1_model

    rng = np.random.default_rng(seed)
    g1 = g1_model()
    q = pin.neutral(g1.model)
    q[3:7] = pin.Quaternion(*rng.normal(size=4)).normalized().coeffs()
    q[g1.base_nq:] = rng.uniform(g1.q_min, g1.q_max)
    for subject, state in ((g1, q), (robot, arm_q)):
        dq = rng.normal(size=subject.nv)
        terms = subject.update_terms(subject.empty_terms(), state, dq)
        data = subject.model.createData()
        subject.pinocchio_pass(data, state, dq)
        if subject.base_nv:
            np.testing.assert_array_equal(terms.body.M_inv, np.triu(data.Minv) + np.triu(data.Minv, 1).T)
            np.testing.assert_array_equal(terms.com, data.com[0])
            np.testing.assert_array_equal(terms.dJcom_dq, data.acom[0])
            np.testing.assert_array_equal(terms.Jcom, data.Jcom)
            np.testing.assert_array_equal(terms.inertia_com, data.Ig.inertia)
        else:
            np.testing.assert_array_equal(terms.M, data.M)
            np.testing.assert_array_equal(terms.h, data.nle)
