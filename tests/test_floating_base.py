"""First-principles checks of the floating-base jump predictors (controller/model/floating_base.py)."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import unit_vectors
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.floating_base import (
    METHODS,
    FloatingBaseModel,
    crb_inverse_inertia,
    gm_inverse_inertia,
    jump_from_impulse,
    predict,
)
from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=20, deadline=None)
speeds = st.floats(0.01, 1.0)
restitutions = st.floats(0.0, 1.0)


@pytest.fixture(scope="module")
def humanoid() -> FloatingBaseModel:
    return FloatingBaseModel()


def configurations():
    """q: a random base placement (position, unit quaternion) and joints 10-90 % into their range."""
    model = FloatingBaseModel()
    lo, hi = model.q_min, model.q_max
    joints = st.lists(st.floats(0.1, 0.9), min_size=lo.size, max_size=lo.size).map(lambda u: lo + np.array(u) * (hi - lo))
    position = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)
    quaternion = st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.2)
    return st.tuples(position, quaternion, joints).map(
        lambda t: np.concatenate([t[0], np.array(t[1]) / np.linalg.norm(t[1]), t[2]])
    )


def approach(normal, speed, tangent_seed):
    """v- = -speed n + a tangential part orthogonal to n."""
    return -speed * normal + 0.3 * speed * np.cross(normal, tangent_seed)


def welded_inverse_inertia(humanoid, q):
    """J M^-1 J^T at the contact point of the whole robot welded at q into one free rigid body,
    built from the per-link inertias (no CCRBA)."""
    model, data = humanoid.model, humanoid.model.createData()
    pin.framesForwardKinematics(model, data, q)
    body = pin.Inertia.Zero()
    for i in range(1, model.njoints):
        body += data.oMi[i].act(model.inertias[i])
    free = pin.Model()
    joint = free.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "welded_robot")
    free.appendBodyToJoint(joint, body, pin.SE3.Identity())
    tip = free.addFrame(pin.Frame("tip", joint, 0, data.oMf[humanoid.contact_frame_id], pin.FrameType.OP_FRAME))
    fdata = free.createData()
    q0 = pin.neutral(free)
    M = pin.crba(free, fdata, q0)
    M = np.triu(M) + np.triu(M, 1).T
    J = pin.computeFrameJacobian(free, fdata, q0, tip, pin.LOCAL_WORLD_ALIGNED)[:3]
    return J @ np.linalg.solve(M, J.T), body.mass


@SETTINGS
@given(q=configurations())
def test_crb_inverse_inertia_is_the_welded_robot(humanoid, q):
    terms = humanoid.terms(q)
    W, mass = welded_inverse_inertia(humanoid, q)
    assert terms.mass == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(crb_inverse_inertia(terms), W, atol=1e-10 * np.abs(W).max())


@SETTINGS
@given(q=configurations())
def test_holding_the_feet_makes_the_hand_heavier(humanoid, q):
    """W_gm (feet held) <= J M^-1 J^T (feet free): constraints only remove mobility; both SPD."""
    terms = humanoid.terms(q)
    W = gm_inverse_inertia(terms)
    W_free = terms.J @ np.linalg.solve(terms.M, terms.J.T)
    assert np.linalg.eigvalsh(W)[0] > 0.0
    assert np.linalg.eigvalsh(W_free - W)[0] > -1e-8 * np.abs(W_free).max()


@SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_classical_reaches_the_velocity_change_with_the_feet_still(humanoid, q, n, s, v, cr):
    """Eq. (6) with the feet held: J dv = -(1+c_r) v-, Jf dv = 0, M dv = J^T iota + Jf^T lambda."""
    terms = humanoid.terms(q)
    v_minus = approach(n, v, s)
    jump = predict(terms, "classical", n, v_minus, cr)
    np.testing.assert_allclose(terms.J @ jump.dv, -(1 + cr) * v_minus, atol=1e-8 * v)
    np.testing.assert_allclose(terms.Jf @ jump.dv, 0.0, atol=1e-8 * v)
    generalized = terms.J.T @ jump.impulse + terms.Jf.T @ jump.feet_impulse
    np.testing.assert_allclose(terms.M @ jump.dv, generalized, atol=1e-8 * np.abs(generalized).max())


@SETTINGS
@given(q=configurations(), impulse=st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3))
def test_linear_momentum_changes_by_the_hand_and_feet_impulses(humanoid, q, impulse):
    """m dc = iota + f_left + f_right: the feet's forces are the first three rows of each wrench."""
    terms = humanoid.terms(q)
    impulse = np.array(impulse)
    dv = jump_from_impulse(terms, impulse)
    feet = terms.feet_impulse(impulse)
    total = impulse + feet[:3] + feet[6:9]
    np.testing.assert_allclose(terms.mass * (terms.Jcom @ dv), total, atol=1e-8 * (1 + np.abs(feet).max()))


@SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, cr=restitutions)
def test_gm_and_crb_change_the_normal_velocity_with_the_feet_still(humanoid, q, n, s, v, cr):
    """(12) with (21)/(23): n.J dv = -(1+c_r) n.v-, Jf dv = 0, iota along n and pushing."""
    terms = humanoid.terms(q)
    v_minus = approach(n, v, s)
    for method in ("gm", "crb"):
        jump = predict(terms, method, n, v_minus, cr)
        assert n @ terms.J @ jump.dv == pytest.approx(-(1 + cr) * (n @ v_minus), rel=1e-7)
        np.testing.assert_allclose(terms.Jf @ jump.dv, 0.0, atol=1e-8 * v)
        np.testing.assert_allclose(np.cross(jump.impulse, n), 0.0, atol=1e-12 * (1 + np.abs(jump.impulse).max()))
        assert jump.impulse @ n >= 0.0
        np.testing.assert_allclose(jump.com_jump, terms.Jcom @ jump.dv)


@SETTINGS
@given(q=configurations())
def test_feet_held_pseudo_inverse_is_a_right_inverse(humanoid, q):
    terms = humanoid.terms(q)
    Jsharp = terms.feet_held_pinv()
    np.testing.assert_allclose(terms.J @ Jsharp, np.eye(3), atol=1e-8)
    np.testing.assert_allclose(terms.Jf @ Jsharp, 0.0, atol=1e-8)


@SETTINGS
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), v=speeds, k=st.floats(0.1, 10.0), cr=restitutions)
def test_jumps_are_linear_in_speed_and_in_one_plus_restitution(humanoid, q, n, s, v, k, cr):
    terms = humanoid.terms(q)
    v_minus = approach(n, v, s)
    for method in METHODS:
        base = predict(terms, method, n, v_minus, 0.0)
        scaled = predict(terms, method, n, k * v_minus, 0.0)
        bounced = predict(terms, method, n, v_minus, cr)
        for field in ("dv", "impulse", "feet_impulse", "com_jump"):
            ref = getattr(base, field)
            tol = 1e-9 * (1 + np.abs(ref).max())
            np.testing.assert_allclose(getattr(scaled, field), k * ref, rtol=1e-8, atol=k * tol)
            np.testing.assert_allclose(getattr(bounced, field), (1 + cr) * ref, rtol=1e-8, atol=2 * tol)


@settings(max_examples=10, deadline=None)
@given(q=configurations(), n=unit_vectors(), s=unit_vectors(), axis=unit_vectors(), angle=st.floats(-np.pi, np.pi),
       shift=st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_jumps_do_not_depend_on_the_world_frame(humanoid, q, n, s, axis, angle, shift):
    """Move the whole scene by a rigid motion X = (R, t): the generalized-velocity jump (base twist
    in the base frame, joint rates) is unchanged; impulses and CoM jumps turn with R."""
    X = pin.SE3(pin.exp3(angle * axis), np.array(shift))
    moved = q.copy()
    base = slice(humanoid.base_nq)  # position and quaternion
    moved[base] = pin.SE3ToXYZQUAT(X * pin.XYZQUATToSE3(q[base]))
    terms, mterms = humanoid.terms(q), humanoid.terms(moved)
    R = X.rotation
    v_minus = approach(n, 0.2, s)
    np.testing.assert_allclose(crb_inverse_inertia(mterms), R @ crb_inverse_inertia(terms) @ R.T, atol=1e-10)
    W = gm_inverse_inertia(terms)
    np.testing.assert_allclose(gm_inverse_inertia(mterms), R @ W @ R.T, atol=1e-8 * np.abs(W).max())
    for method in METHODS:
        a, b = predict(terms, method, n, v_minus), predict(mterms, method, R @ n, R @ v_minus)
        np.testing.assert_allclose(b.dv, a.dv, atol=1e-7 * (1 + np.abs(a.dv).max()))
        np.testing.assert_allclose(b.impulse, R @ a.impulse, atol=1e-7 * (1 + np.abs(a.impulse).max()))
        np.testing.assert_allclose(b.com_jump, R @ a.com_jump, atol=1e-7 * (1 + np.abs(a.com_jump).max()))


def test_sole_corners_follow_the_feet(humanoid):
    """At the neutral configuration both soles are flat and at the same height."""
    q = pin.neutral(humanoid.model)
    corners = humanoid.sole_corners(q)
    assert corners.shape == (8, 3)
    np.testing.assert_allclose(corners[:, 2], corners[0, 2], atol=1e-9)
    placements = humanoid.frame_placements(q)
    left, right = humanoid.foot_frames
    assert placements[left].translation[1] > placements[right].translation[1]  # left is +y


def test_bad_input_is_refused(humanoid):
    terms = humanoid.terms(pin.neutral(humanoid.model))
    n, v = np.array([-1.0, 0.0, 0.0]), np.array([0.2, 0.0, 0.0])
    with pytest.raises(BadInputError):
        predict(terms, "pendulum", n, v)
    with pytest.raises(BadInputError):
        predict(terms, "crb", n, v, 1.5)
    with pytest.raises(BadInputError):
        predict(terms, "crb", np.zeros(3), v)
    with pytest.raises(BadInputError):
        predict(terms, "crb", n, [np.nan, 0.0, 0.0])
    with pytest.raises(BadInputError):
        humanoid.terms(np.zeros(5))
