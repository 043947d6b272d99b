"""First-principles checks of the jump predictors (controller/model/jump.py, its kernels
controller/model/jump_kernels.py): the fixed-base arms', and the held-contact form of the
standing G1 (its predictions, and its compiled maps against them)."""

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from conftest import JOINTS, joint_positions, unit_vectors
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from reference.jump import (
    reference_crb_inverse_inertia_times,
    reference_crb_jump,
    reference_crb_unit_maps,
    reference_rank_one_jump_matrices,
)
from reference.whole_body import feet_held_pinv
from whole_body_states import standing_states, upright
from whole_body_states import robot as g1

from impactqp.controller.model.capture import com_jump_map
from impactqp.controller.model.jump import (
    JUMP_MODELS,
    METHODS,
    crb_inverse_inertia,
    gm_inverse_inertia,
    held_impulse,
    held_pinv,
    jump_from_impulse,
    jump_model,
    predict,
)
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS, held_contact_maps
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, SingularPostureError
from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=40, deadline=None)
speeds = st.floats(0.01, 1.0)
restitutions = st.floats(0.0, 1.0)


def approach(normal, speed, tangent_seed):
    """v- = -speed n + a tangential part orthogonal to n."""
    t = np.cross(normal, tangent_seed)
    return -speed * normal + 0.3 * speed * t


def terms_or_skip(robot, q):
    """The model terms at q; a singular posture is rejected as an example (hypothesis)."""
    try:
        return robot.terms(q)
    except SingularPostureError:
        reject()


@SETTINGS
@given(q=joint_positions(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_classical_reaches_the_full_velocity_change(robot, q, n, s, v, cr):
    """Eq. (6) satisfies J ddq_c = dv = -(1+c_r) v- (joint motion constraint (10))."""
    terms = terms_or_skip(robot, q)
    v_minus = approach(n, v, s)
    pred = JUMP_MODELS["classical"].predict(terms, n, v_minus, cr)
    np.testing.assert_allclose(terms.J @ pred.dq_jump, -(1 + cr) * v_minus, atol=1e-9)
    # and it is the M-weighted least-squares solution (7): M ddq lies in range(J^T)
    np.testing.assert_allclose(terms.M @ pred.dq_jump, terms.J.T @ pred.impulse, atol=1e-9)


@SETTINGS
@given(q=joint_positions(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_normal_velocity_change_of_gm_and_crb(robot, q, n, s, v, cr):
    """With (12) and (17): n.J ddq = n.W iota = -(1+c_r) n.v-, and iota is along n."""
    terms = terms_or_skip(robot, q)
    v_minus = approach(n, v, s)
    for name in ("gm", "crb"):
        pred = JUMP_MODELS[name].predict(terms, n, v_minus, cr)
        assert n @ terms.J @ pred.dq_jump == pytest.approx(-(1 + cr) * (n @ v_minus), rel=1e-9)
        np.testing.assert_allclose(np.cross(pred.impulse, n), 0.0, atol=1e-12)
        assert pred.impulse @ n >= 0.0  # the surface pushes: iota_n >= 0 when approaching


def welded_arm_inverse_inertia(robot: PandaModel, q: np.ndarray) -> np.ndarray:
    """J M^-1 J^T of the arm welded at q into one free-floating rigid body, built independently.

    Every link's spatial inertia is moved to the world frame and summed into one body attached to
    a free-flyer joint at the world origin; the contact point becomes a frame of that body.
    """
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    body = pin.Inertia.Zero()
    for i in range(1, robot.model.njoints):
        body += data.oMi[i].act(robot.model.inertias[i])
    free = pin.Model()
    joint = free.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "welded_arm")
    free.appendBodyToJoint(joint, body, pin.SE3.Identity())
    tip = free.addFrame(pin.Frame("tip", joint, 0, robot.contact_frame(q), pin.FrameType.OP_FRAME))
    fdata = free.createData()
    q0 = pin.neutral(free)
    M = pin.crba(free, fdata, q0)
    M = np.triu(M) + np.triu(M, 1).T
    J = pin.computeFrameJacobian(free, fdata, q0, tip, pin.LOCAL_WORLD_ALIGNED)[:3]
    return J @ np.linalg.solve(M, J.T)


@SETTINGS
@given(q=joint_positions())
def test_crb_inverse_inertia_is_the_welded_arm(robot, q):
    terms = terms_or_skip(robot, q)
    np.testing.assert_allclose(crb_inverse_inertia(terms), welded_arm_inverse_inertia(robot, q), atol=1e-12)


@SETTINGS
@given(q=joint_positions())
def test_inverse_inertias_are_symmetric_positive_definite(robot, q):
    terms = terms_or_skip(robot, q)
    for W in (crb_inverse_inertia(terms), gm_inverse_inertia(terms)):
        np.testing.assert_allclose(W, W.T, atol=1e-12)
        assert np.linalg.eigvalsh(W)[0] > 0.0


@SETTINGS
@given(q=joint_positions(), n=unit_vectors(), s=unit_vectors(), v=speeds, k=st.floats(0.1, 10.0), cr=restitutions)
def test_jumps_are_linear_in_speed_and_in_one_plus_restitution(robot, q, n, s, v, k, cr):
    terms = terms_or_skip(robot, q)
    v_minus = approach(n, v, s)
    for name, model in JUMP_MODELS.items():
        base = model.predict(terms, n, v_minus, 0.0).dq_jump
        np.testing.assert_allclose(model.predict(terms, n, k * v_minus, 0.0).dq_jump, k * base, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(model.predict(terms, n, v_minus, cr).dq_jump, (1 + cr) * base, rtol=1e-9, atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(q=joint_positions(0.3), n=unit_vectors(), s=unit_vectors(), angle=st.floats(-np.pi, np.pi))
def test_jump_is_invariant_to_rotating_the_scene_about_the_vertical(robot, q, n, s, angle):
    """Rotate base, surface normal and velocity about z: same jumps, impulses rotated."""
    R = pin.utils.rpyToMatrix(0.0, 0.0, angle)
    rotated = PandaModel(base_placement=pin.SE3(R, np.zeros(3)))
    terms, rterms = terms_or_skip(robot, q), terms_or_skip(rotated, q)
    v_minus = approach(n, 0.15, s)
    for name, model in JUMP_MODELS.items():
        a = model.predict(terms, n, v_minus, 0.2)
        b = model.predict(rterms, R @ n, R @ v_minus, 0.2)
        np.testing.assert_allclose(b.dq_jump, a.dq_jump, atol=1e-9)
        np.testing.assert_allclose(b.impulse, R @ a.impulse, atol=1e-9)


@SETTINGS
@given(q=joint_positions(), n=unit_vectors(), s=unit_vectors())
def test_measured_impulse_variant_reproduces_the_prediction(robot, q, n, s):
    terms = terms_or_skip(robot, q)
    v_minus = approach(n, 0.12, s)
    for model in JUMP_MODELS.values():
        own = model.predict(terms, n, v_minus, 0.1)
        fed = model.predict(terms, n, v_minus, 0.1, impulse=own.impulse)
        np.testing.assert_allclose(fed.dq_jump, own.dq_jump, atol=1e-12)


@pytest.mark.parametrize("impulse, match", [([np.nan, 0.0, 0.0], "finite"), ([1.0, 0.0], "3 numbers"), ("abc", "real numbers")])
def test_a_given_impulse_that_is_not_three_finite_numbers_is_bad_input(robot, impulse, match):
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    for model in JUMP_MODELS.values():
        with pytest.raises(BadInputError, match=match):
            model.predict(terms, [-1.0, 0.0, 0.0], None, 0.0, impulse=impulse)
    with pytest.raises(BadInputError, match=match):
        jump_from_impulse(terms, impulse)


@SETTINGS
@given(q=joint_positions(), n=unit_vectors(), s=unit_vectors())
def test_jump_matrix_maps_pre_impact_joint_velocity(robot, q, n, s):
    """A dq- equals the prediction for v- = J dq-."""
    terms = terms_or_skip(robot, q)
    dq_minus = terms.J_pinv @ approach(n, 0.1, s) + 0.05 * s[0] * np.ones(JOINTS)
    for model in JUMP_MODELS.values():
        A = model.jump_matrix(terms, n, 0.3)
        expected = model.predict(terms, n, terms.J @ dq_minus, 0.3).dq_jump
        np.testing.assert_allclose(A @ dq_minus, expected, atol=1e-10)


def test_normal_is_normalised(robot):
    terms = robot.terms(np.array([0.1, -0.4, 0.2, -2.0, 0.3, 2.2, 0.4]))
    n = np.array([-1.0, 0.2, 0.1]) / np.linalg.norm([-1.0, 0.2, 0.1])
    for model in JUMP_MODELS.values():
        a = model.predict(terms, n, -0.1 * n, 0.0)
        b = model.predict(terms, 3.0 * n, -0.1 * n, 0.0)
        np.testing.assert_allclose(b.dq_jump, a.dq_jump, atol=1e-12)
        np.testing.assert_allclose(model.jump_matrix(terms, 3.0 * n, 0.0), model.jump_matrix(terms, n, 0.0), atol=1e-12)
    with pytest.raises(ValueError, match="non-zero"):
        JUMP_MODELS["crb"].predict(terms, np.zeros(3), np.zeros(3), 0.0)


def test_classical_normal_keeps_only_the_normal_impulse(robot):
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 2.2, 0.4])
    terms = robot.terms(q)
    n = np.array([-1.0, 0.0, 0.0])
    full = JUMP_MODELS["classical"].predict(terms, n, -0.1 * n, 0.0)
    normal = JUMP_MODELS["classical_normal"].predict(terms, n, -0.1 * n, 0.0)
    np.testing.assert_allclose(normal.impulse, (full.impulse @ n) * n)


def test_crb_never_uses_the_joint_space_inertia(robot):
    """The CRB path runs with M replaced by NaNs and M^-1 computed at a NaN posture: it never
    forms or inverts M; a prediction from q does not even fill M (a lazily filled field)."""
    q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 2.2, 0.4])
    n = np.array([-1.0, 0.0, 0.0])
    fresh = robot.terms(q)
    JUMP_MODELS["crb"].predict(fresh, n, -0.1 * n, 0.0)
    assert "M" not in vars(fresh)
    terms = dataclasses.replace(
        fresh, M=np.full((JOINTS, JOINTS), np.nan), compute_inverse_inertia=lambda _: robot.inverse_inertia(q * np.nan)
    )
    pred = JUMP_MODELS["crb"].predict(terms, n, -0.1 * n, 0.0)
    assert np.all(np.isfinite(pred.dq_jump))
    assert not np.all(np.isfinite(JUMP_MODELS["gm"].predict(terms, n, -0.1 * n, 0.0).dq_jump))


def test_methods_are_registered():
    assert set(METHODS) == set(JUMP_MODELS) == {"classical", "classical_normal", "gm", "crb"}


@SETTINGS
@given(q=joint_positions(), normal=unit_vectors())
def test_inverse_inertia_along_the_normal_is_W_times_n(robot, q, normal):
    """The closed forms of W n used by the controller equal the full W (20), (22) times n."""
    terms = terms_or_skip(robot, q)
    np.testing.assert_allclose(
        JUMP_MODELS["crb"].inverse_inertia_times(terms, normal), crb_inverse_inertia(terms) @ normal, atol=1e-12
    )
    np.testing.assert_allclose(  # the kernel's plain-float reference
        reference_crb_inverse_inertia_times(terms, normal), crb_inverse_inertia(terms) @ normal,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        JUMP_MODELS["gm"].inverse_inertia_times(terms, normal), gm_inverse_inertia(terms) @ normal,
        rtol=1e-8, atol=1e-12,
    )


@SETTINGS
@given(q=joint_positions(), normal=unit_vectors(), cr=restitutions)
def test_compiled_crb_maps_equal_the_numpy_reference(robot, q, normal, cr):
    """The compiled G, K and W of the CRB model equal eq. (20) then (12) and (21) in numpy."""
    terms = terms_or_skip(robot, q)
    crb = JUMP_MODELS["crb"]
    for fast, reference in zip(
        dataclasses.astuple(crb.unit_maps(terms, normal, cr)),
        dataclasses.astuple(reference_crb_unit_maps(terms, normal, cr)),
    ):
        np.testing.assert_allclose(fast, reference, rtol=1e-9, atol=1e-12)


@SETTINGS
@given(q=joint_positions(), normal=unit_vectors(), velocity=unit_vectors(), cr=restitutions)
def test_compiled_crb_prediction_equals_the_numpy_reference(robot, q, normal, velocity, cr):
    """One compiled CRB prediction from q (``crb_jump``) equals eq. (20), (12) and (21) in numpy,
    and the general path's G v- and K iota (``JumpModel.predict`` with a measured impulse)."""
    terms = terms_or_skip(robot, q)
    crb = JUMP_MODELS["crb"]
    fast = crb.predict(terms, normal, velocity, cr)
    for value, reference in zip((fast.dq_jump, fast.impulse, fast.W), reference_crb_jump(terms, normal, velocity, cr)):
        np.testing.assert_allclose(value, reference, rtol=1e-9, atol=1e-12)
    maps = crb.unit_maps(terms, normal, cr)
    general = crb.predict(terms, normal, velocity, cr, impulse=maps.G @ velocity)
    np.testing.assert_allclose(fast.dq_jump, general.dq_jump, rtol=1e-9, atol=1e-12)


@SETTINGS
@given(q=joint_positions(), normal=unit_vectors(), cr=restitutions)
def test_compiled_rank_one_matrices_equal_the_numpy_reference(robot, q, normal, cr):
    """The compiled rank-one A and P of the normal-impulse models equal their numpy statement,
    and both equal K G J and J^T G J from the models' own G and K."""
    terms = terms_or_skip(robot, q)
    for name in ("gm", "crb"):
        model = JUMP_MODELS[name]
        fast = model.unit_matrices(terms, normal, cr)
        maps = model.unit_maps(terms, normal, cr)
        assert fast.com_map is None
        for a, b in zip(fast[:3], reference_rank_one_jump_matrices(model, terms, normal, cr)[:3]):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(fast.impulse_map, maps.G, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(fast.jump_matrix, maps.K @ maps.G @ terms.J, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(fast.torque_matrix, terms.J.T @ maps.G @ terms.J, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("name", METHODS)
@pytest.mark.parametrize("restitution", [-0.1, 1.5, float("nan"), "0.3", True])
def test_every_entry_point_refuses_a_restitution_outside_zero_one(robot, name, restitution):
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    model = JUMP_MODELS[name]
    normal, v = np.array([-1.0, 0.0, 0.0]), np.array([0.1, 0.0, 0.0])
    for call in (
        lambda: model.maps(terms, normal, restitution),
        lambda: model.jump_matrix(terms, normal, restitution),
        lambda: model.predict(terms, normal, v, restitution),
    ):
        with pytest.raises(BadInputError, match=r"\[0, 1\]"):
            call()


@pytest.mark.parametrize("name", METHODS)
def test_every_entry_point_refuses_a_zero_or_non_finite_normal(robot, name):
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    model = JUMP_MODELS[name]
    for normal in ([0.0, 0.0, 0.0], [np.nan, 0.0, 1.0]):
        with pytest.raises(BadInputError, match="the surface normal"):
            model.maps(terms, normal, 0.0)
        with pytest.raises(BadInputError, match="the surface normal"):
            model.predict(terms, normal, np.zeros(3), 0.0)


@SETTINGS
@given(q=joint_positions(), normal=unit_vectors(), cr=restitutions, seed=st.integers(0, 2**31))
def test_held_contact_maps_with_no_held_contact_are_the_arms_maps(robot, q, normal, cr, seed):
    """With Jf empty (a fixed base: the terms' held_jacobian has no rows), P_f = M^-1 and
    J# = J+: the held-contact kernel gives the arm's A, P and G, and C = Jcom M^-1 J^T for any
    Jcom."""
    terms = terms_or_skip(robot, q)
    assert terms.held_jacobian.shape == (0, robot.nv)
    Jcom = np.random.default_rng(seed).normal(size=(3, robot.nv))
    M_inv = np.linalg.inv(terms.M)
    rigid = (terms.contact_point, terms.com, terms.inertia_com, terms.mass)
    for code, name in enumerate(HELD_CONTACT_METHODS):
        arm = JUMP_MODELS[name].unit_matrices(terms, normal, cr)
        A, P, G, C = held_contact_maps(M_inv, terms.J6, terms.held_jacobian, Jcom, rigid, code, normal, cr)
        for general, fixed in ((A, arm.jump_matrix), (P, arm.torque_matrix), (G, arm.impulse_map)):
            np.testing.assert_allclose(general, fixed, rtol=1e-7, atol=1e-9 * (1 + np.abs(fixed).max()))
        np.testing.assert_allclose(C, Jcom @ np.linalg.solve(terms.M, terms.J.T), rtol=1e-8, atol=1e-10)


G1_SETTINGS = settings(max_examples=15, deadline=None)


@G1_SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0), st.sampled_from(HELD_CONTACT_METHODS), unit_vectors(),
       st.floats(0.0, 1.0))
def test_held_contact_maps_give_the_g1_predictors_jump_impulse_and_com_map(state, method, normal, restitution):
    """With the feet held: A v = dv and G J v = iota of ``predict`` (M's Cholesky factor,
    J# = N (J N)^+) at v- = J v, from the kernel's M^-1 and J# = N J^T (J N J^T)^-1;
    P = J^T G J; C = Jcom P_f J^T."""
    _, q, v = state
    terms, base = g1().terms(q, v), g1().terms(q)
    maps = jump_model(method).unit_matrices(terms, normal, restitution)
    if abs(normal @ terms.J @ v) < 1e-3:
        v = v + feet_held_pinv(terms.J, terms.held_jacobian) @ (-0.1 * normal)
    jump = predict(base, method, normal, terms.J @ v, restitution)
    scale = 1.0 + np.abs(jump.dq_jump).max()
    np.testing.assert_allclose(maps.jump_matrix @ v, jump.dq_jump, atol=1e-8 * scale)
    np.testing.assert_allclose(maps.impulse_map @ (terms.J @ v), jump.impulse, atol=1e-8 * (1 + np.abs(jump.impulse).max()))
    np.testing.assert_allclose(maps.torque_matrix, terms.J.T @ maps.impulse_map @ terms.J, atol=1e-9 * scale)
    np.testing.assert_allclose(maps.com_map, com_jump_map(base), atol=1e-10)


@G1_SETTINGS
@given(standing_states(max_joint_offset=0.3))
def test_feet_held_pinv_is_a_right_inverse_that_keeps_the_feet_still(state):
    _, q, _ = state
    terms = g1().terms(q)
    Jsharp = feet_held_pinv(terms.J, terms.held_jacobian)
    np.testing.assert_allclose(terms.J @ Jsharp, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(terms.held_jacobian @ Jsharp, 0.0, atol=1e-9)
    np.testing.assert_allclose(Jsharp, held_pinv(terms), atol=1e-8)


def test_a_model_without_a_held_contact_form_is_refused_with_held_contacts():
    terms = g1().terms(upright())
    with pytest.raises(BadInputError):
        JUMP_MODELS["classical_normal"].unit_matrices(terms, np.array([-1.0, 0, 0]), 0.0)
    with pytest.raises(BadInputError, match="no held-contact form"):
        predict(terms, "classical_normal", np.array([-1.0, 0, 0]), np.array([0.2, 0, 0]))


def configurations():
    """q: a random base placement (position, unit quaternion) and joints 10-90 % into their range."""
    model = g1()
    lo, hi = model.q_min, model.q_max
    joints = st.lists(st.floats(0.1, 0.9), min_size=lo.size, max_size=lo.size).map(lambda u: lo + np.array(u) * (hi - lo))
    position = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)
    quaternion = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.2)
    return st.tuples(position, quaternion, joints).map(
        lambda t: np.concatenate([t[0], np.array(t[1]) / np.linalg.norm(t[1]), t[2]])
    )


def welded_inverse_inertia(q):
    """J M^-1 J^T at the contact point of the whole robot welded at q into one free rigid body,
    built from the per-link inertias (no CCRBA)."""
    model, data = g1().model, g1().model.createData()
    pin.framesForwardKinematics(model, data, q)
    body = pin.Inertia.Zero()
    for i in range(1, model.njoints):
        body += data.oMi[i].act(model.inertias[i])
    free = pin.Model()
    joint = free.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "welded_robot")
    free.appendBodyToJoint(joint, body, pin.SE3.Identity())
    tip = free.addFrame(pin.Frame("tip", joint, 0, data.oMf[g1().contact_frame_id], pin.FrameType.OP_FRAME))
    fdata = free.createData()
    q0 = pin.neutral(free)
    M = pin.crba(free, fdata, q0)
    M = np.triu(M) + np.triu(M, 1).T
    J = pin.computeFrameJacobian(free, fdata, q0, tip, pin.LOCAL_WORLD_ALIGNED)[:3]
    return J @ np.linalg.solve(M, J.T), body.mass


@G1_SETTINGS
@given(q=configurations())
def test_g1_crb_inverse_inertia_is_the_welded_robot(q):
    terms = g1().terms(q)
    W, mass = welded_inverse_inertia(q)
    assert terms.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(crb_inverse_inertia(terms), W, atol=1e-10 * np.abs(W).max())


@G1_SETTINGS
@given(q=configurations())
def test_g1_holding_the_feet_makes_the_hand_heavier(q):
    """W_gm (feet held) <= J M^-1 J^T (feet free): constraints only remove mobility; both SPD."""
    terms = g1().terms(q)
    W = gm_inverse_inertia(terms)
    W_free = terms.J @ np.linalg.solve(terms.M, terms.J.T)
    assert np.linalg.eigvalsh(W)[0] > 0.0
    assert np.linalg.eigvalsh(W_free - W)[0] > -1e-8 * np.abs(W_free).max()


@G1_SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_g1_classical_reaches_the_velocity_change_with_the_feet_still(q, n, s, v, cr):
    """Eq. (6) with the feet held: J dv = -(1+c_r) v-, Jf dv = 0, M dv = J^T iota + Jf^T lambda."""
    terms = g1().terms(q)
    v_minus = approach(n, v, s)
    jump = predict(terms, "classical", n, v_minus, cr)
    np.testing.assert_allclose(terms.J @ jump.dq_jump, -(1 + cr) * v_minus, atol=1e-8 * v)
    np.testing.assert_allclose(terms.held_jacobian @ jump.dq_jump, 0.0, atol=1e-8 * v)
    generalized = terms.J.T @ jump.impulse + terms.held_jacobian.T @ jump.held_impulse
    np.testing.assert_allclose(terms.M @ jump.dq_jump, generalized, atol=1e-8 * np.abs(generalized).max())


@G1_SETTINGS
@given(q=configurations(), impulse=st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3))
def test_g1_linear_momentum_changes_by_the_hand_and_feet_impulses(q, impulse):
    """m dc = iota + f_left + f_right: the feet's forces are the first three rows of each wrench."""
    terms = g1().terms(q)
    impulse = np.array(impulse)
    dv = jump_from_impulse(terms, impulse)
    feet = held_impulse(terms, impulse)
    total = impulse + feet[:3] + feet[6:9]
    np.testing.assert_allclose(terms.mass * (terms.Jcom @ dv), total, atol=1e-8 * (1 + np.abs(feet).max()))


@G1_SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_g1_gm_and_crb_change_the_normal_velocity_with_the_feet_still(q, n, s, v, cr):
    """(12) with (21)/(23): n.J dv = -(1+c_r) n.v-, Jf dv = 0, iota along n and pushing."""
    terms = g1().terms(q)
    v_minus = approach(n, v, s)
    for method in ("gm", "crb"):
        jump = predict(terms, method, n, v_minus, cr)
        assert n @ terms.J @ jump.dq_jump == pytest.approx(-(1 + cr) * (n @ v_minus), rel=1e-7)
        np.testing.assert_allclose(terms.held_jacobian @ jump.dq_jump, 0.0, atol=1e-8 * v)
        np.testing.assert_allclose(np.cross(jump.impulse, n), 0.0, atol=1e-12 * (1 + np.abs(jump.impulse).max()))
        assert jump.impulse @ n >= 0.0
        np.testing.assert_allclose(jump.com_jump, terms.Jcom @ jump.dq_jump)


@G1_SETTINGS
@given(q=configurations())
def test_g1_feet_held_pseudo_inverse_is_a_right_inverse(q):
    terms = g1().terms(q)
    Jsharp = held_pinv(terms)
    np.testing.assert_allclose(terms.J @ Jsharp, np.eye(3), atol=1e-8)
    np.testing.assert_allclose(terms.held_jacobian @ Jsharp, 0.0, atol=1e-8)


@G1_SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, k=st.floats(0.1, 10.0), cr=restitutions)
def test_g1_jumps_are_linear_in_speed_and_in_one_plus_restitution(q, n, s, v, k, cr):
    terms = g1().terms(q)
    v_minus = approach(n, v, s)
    for method in HELD_CONTACT_METHODS:
        base = predict(terms, method, n, v_minus, 0.0)
        scaled = predict(terms, method, n, k * v_minus, 0.0)
        bounced = predict(terms, method, n, v_minus, cr)
        for field in ("dq_jump", "impulse", "held_impulse", "com_jump"):
            ref = getattr(base, field)
            tol = 1e-9 * (1 + np.abs(ref).max())
            np.testing.assert_allclose(getattr(scaled, field), k * ref, rtol=1e-8, atol=k * tol)
            np.testing.assert_allclose(getattr(bounced, field), (1 + cr) * ref, rtol=1e-8, atol=2 * tol)


@settings(max_examples=10, deadline=None)
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), axis=unit_vectors(), angle=st.floats(-np.pi, np.pi),
       shift=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_g1_jumps_do_not_depend_on_the_world_frame(q, n, s, axis, angle, shift):
    """Move the whole scene by a rigid motion X = (R, t): the generalized-velocity jump (base twist
    in the base frame, joint rates) is unchanged; impulses and CoM jumps turn with R."""
    X = pin.SE3(pin.exp3(angle * axis), np.array(shift))
    moved = q.copy()
    base = slice(g1().base_nq)  # position and quaternion
    moved[base] = pin.SE3ToXYZQUAT(X * pin.XYZQUATToSE3(q[base]))
    terms, mterms = g1().terms(q), g1().terms(moved)
    R = X.rotation
    v_minus = approach(n, 0.2, s)
    np.testing.assert_allclose(crb_inverse_inertia(mterms), R @ crb_inverse_inertia(terms) @ R.T, atol=1e-10)
    W = gm_inverse_inertia(terms)
    np.testing.assert_allclose(gm_inverse_inertia(mterms), R @ W @ R.T, atol=1e-8 * np.abs(W).max())
    for method in HELD_CONTACT_METHODS:
        a, b = predict(terms, method, n, v_minus), predict(mterms, method, R @ n, R @ v_minus)
        np.testing.assert_allclose(b.dq_jump, a.dq_jump, atol=1e-7 * (1 + np.abs(a.dq_jump).max()))
        np.testing.assert_allclose(b.impulse, R @ a.impulse, atol=1e-7 * (1 + np.abs(a.impulse).max()))
        np.testing.assert_allclose(b.com_jump, R @ a.com_jump, atol=1e-7 * (1 + np.abs(a.com_jump).max()))


def test_g1_bad_predictor_input_is_refused():
    terms = g1().terms(pin.neutral(g1().model))
    n, v = np.array([-1.0, 0.0, 0.0]), np.array([0.2, 0.0, 0.0])
    with pytest.raises(BadInputError):
        predict(terms, "pendulum", n, v)
    with pytest.raises(BadInputError):
        predict(terms, "crb", n, v, 1.5)
    with pytest.raises(BadInputError):
        predict(terms, "crb", np.zeros(3), v)
    with pytest.raises(BadInputError):
        predict(terms, "crb", n, [np.nan, 0.0, 0.0])


@pytest.mark.parametrize("method", HELD_CONTACT_METHODS)
def test_held_contacts_that_lose_rank_at_a_state_are_a_singular_posture(method):
    """Held contacts whose stacked Jacobian loses rank at a state (here the left foot's six rows
    held twice: Jf M^-1 Jf^T singular) give SingularPostureError from the compiled maps and from
    ``predict``, not a solver's error."""
    terms = g1().terms(upright())
    Jf = terms.held_jacobian
    twice = dataclasses.replace(terms, held_jacobian=np.vstack([Jf, Jf[:6]]), held_drift=np.concatenate([terms.held_drift, terms.held_drift[:6]]))
    normal = np.array([-1.0, 0.0, 0.0])
    with pytest.raises(SingularPostureError, match="held contacts' Jacobian is singular"):
        jump_model(method).unit_matrices(twice, normal, 0.0)
    with pytest.raises(SingularPostureError, match="held contacts' Jacobian is singular"):
        predict(twice, method, normal, np.array([0.2, 0.0, 0.0]))
