"""The CRB prediction from q alone (controller.model.crb_prediction) is the general path's
(``CompositeRigidBodyJump.predict`` on ``RobotModel.terms``), on every built-in arm."""

import functools

import numpy as np
import pytest
from conftest import ARMS, unit_vectors
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from reference.crb_prediction import reference_crb_state
from test_jump import welded_arm_inverse_inertia
from test_robot import SINGULAR_Q

from impactqp.controller.model.crb_prediction import (
    CrbPredictor, KinematicTree, crb_batch, crb_state, pack_tree, scratch, unpacked_tree,
)
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.robot import InvalidStateError, RobotModel, SingularPostureError
from impactqp.controller.model.validation import BadInputError

SETTINGS = settings(max_examples=30, deadline=None)
restitutions = st.floats(0.0, 1.0)


@functools.cache
def predictor(name: str) -> CrbPredictor:
    return CrbPredictor(RobotModel(name))


def posture(name: str, unit: np.ndarray) -> np.ndarray:
    """q inside the limits of the arm ``name``, 0.1 rad from each: ``unit`` in [0, 1]^nq."""
    robot = predictor(name).robot
    lo, hi = robot.q_min + 0.1, robot.q_max - 0.1
    return lo + unit[:robot.nq] * (hi - lo)


units = st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7).map(np.array)


def general_or_reject(robot, q, normal, velocity, restitution):
    """The general path's prediction; a singular posture is rejected as an example."""
    try:
        return JUMP_MODELS["crb"].predict(robot.terms(q), normal, velocity, restitution)
    except SingularPostureError:
        reject()


@SETTINGS
@given(name=st.sampled_from(ARMS), unit=units, normal=unit_vectors(), velocity=unit_vectors(), cr=restitutions)
def test_the_prediction_from_q_is_the_general_paths(name, unit, normal, velocity, cr):
    fast = predictor(name)
    q = posture(name, unit)
    expected = general_or_reject(fast.robot, q, 2.0 * normal, 0.3 * velocity, cr)
    got = fast.predict(q, 2.0 * normal, 0.3 * velocity, cr)
    scale = max(1.0, np.abs(expected.dq_jump).max())
    np.testing.assert_allclose(got.dq_jump, expected.dq_jump, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(got.impulse, expected.impulse, rtol=0.0, atol=1e-12 * max(1.0, np.abs(expected.impulse).max()))
    np.testing.assert_allclose(got.W, expected.W, rtol=0.0, atol=1e-12 * np.abs(expected.W).max())
    assert got.method == "crb" and got.held_impulse.shape == (0,) and got.com_jump is None


@SETTINGS
@given(name=st.sampled_from(ARMS), unit=units)
def test_the_compiled_pass_equals_its_numpy_twin(name, unit):
    fast = predictor(name)
    tree = KinematicTree(fast.robot)
    q = posture(name, unit)
    nv = fast.robot.nv
    state, _, work = scratch(nv)
    mass = crb_state(fast.tree, q, state, work)
    for got, expected in zip((*state, mass), reference_crb_state(tree, q)):
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@SETTINGS
@given(name=st.sampled_from(ARMS), unit=units)
def test_w_crb_is_the_inverse_inertia_of_the_welded_arm(name, unit):
    fast = predictor(name)
    q = posture(name, unit)
    general_or_reject(fast.robot, q, np.array([1.0, 0.0, 0.0]), np.zeros(3), 0.0)
    W = fast.predict(q, [1.0, 0.0, 0.0], np.zeros(3), 0.0).W
    np.testing.assert_allclose(W, welded_arm_inverse_inertia(fast.robot, q), atol=1e-12)


@SETTINGS
@given(name=st.sampled_from(ARMS), unit=units, normal=unit_vectors(), velocity=unit_vectors(),
       k=st.floats(0.1, 10.0), cr=restitutions)
def test_the_jump_is_linear_in_speed_and_in_one_plus_restitution_and_meets_eq_12(name, unit, normal, velocity, k, cr):
    """n.J ddq = -(1+c_r) n.v- (eqs. 12, 21), iota along n, and ddq linear in v- and (1+c_r)."""
    fast = predictor(name)
    q = posture(name, unit)
    J = general_or_reject(fast.robot, q, normal, velocity, 0.0) and fast.robot.terms(q).J
    base = fast.predict(q, normal, velocity, 0.0)
    np.testing.assert_allclose(fast.predict(q, normal, k * velocity, 0.0).dq_jump, k * base.dq_jump, rtol=1e-9, atol=1e-12)
    bounced = fast.predict(q, normal, velocity, cr)
    np.testing.assert_allclose(bounced.dq_jump, (1 + cr) * base.dq_jump, rtol=1e-9, atol=1e-12)
    assert normal @ J @ bounced.dq_jump == pytest.approx(-(1 + cr) * (normal @ velocity), rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(np.cross(bounced.impulse, normal), 0.0, atol=1e-12)


@settings(max_examples=10, deadline=None)
@given(name=st.sampled_from(ARMS), seed=st.integers(0, 2**31), normal=unit_vectors(), cr=restitutions)
def test_the_batch_is_the_single_prediction_row_by_row(name, seed, normal, cr):
    fast = predictor(name)
    rng = np.random.default_rng(seed)
    Q = np.array([posture(name, rng.uniform(0.0, 1.0, 7)) for _ in range(12)])
    velocities = rng.normal(size=(12, 3))
    jumps, impulses = fast.predict_batch(Q, 3.0 * normal, velocities, cr)
    # views of rows of larger arrays, as the bench's workers pass their rows of shared memory (the
    # layout of its calls: a strided view would only compile a kernel no caller uses)
    shared = np.zeros((24, fast.robot.nv)), np.zeros((24, 3))
    out = shared[0][5:17], shared[1][5:17]
    assert fast.predict_batch(Q, 3.0 * normal, velocities, cr, out=out) is out
    np.testing.assert_array_equal(out[0], jumps)
    np.testing.assert_array_equal(out[1], impulses)
    assert not np.any(shared[0][np.r_[:5, 17:24]]) and not np.any(shared[1][np.r_[:5, 17:24]])  # the other rows untouched
    for q, velocity, jump, impulse in zip(Q, velocities, jumps, impulses):
        try:
            single = fast.predict(q, normal, velocity, cr)
        except SingularPostureError:
            continue
        # the two round differently near a singularity (the single prediction then takes the general
        # path): their difference grows with the rounding of (J J^T)^-1, eps cond(J)^2
        relative = max(1e-12, 100.0 * np.finfo(float).eps * np.linalg.cond(fast.robot.terms(q).J) ** 2)
        np.testing.assert_allclose(jump, single.dq_jump, rtol=0.0, atol=relative * max(1.0, np.abs(single.dq_jump).max()))
        np.testing.assert_allclose(impulse, single.impulse, rtol=0.0, atol=relative * max(1.0, np.abs(single.impulse).max()))


def test_the_batch_compiles_one_signature_whatever_the_layout_of_its_inputs():
    """Read-only, column-major, broadcast or single-row inputs reach ``crb_batch`` as writable
    row-major copies: one compiled signature, and the same predictions."""
    fast = predictor("panda")
    Q = np.array([posture("panda", np.full(7, u)) for u in (0.3, 0.5, 0.7)])
    normal, velocities = np.array([0.0, 0.0, 1.0]), np.array([[0.0, 0.1, -0.4]] * 3)
    expected = fast.predict_batch(Q, normal, velocities)
    read_only = [array.copy() for array in (Q, np.tile(normal, (3, 1)), velocities)]
    for array in read_only:
        array.flags.writeable = False
    for arguments in (read_only, (np.asfortranarray(Q), normal, velocities[0]), (Q[:1], normal[None], velocities[:1])):
        jumps, impulses = fast.predict_batch(*arguments)
        np.testing.assert_array_equal(jumps, expected[0][:len(jumps)])
        np.testing.assert_array_equal(impulses, expected[1][:len(jumps)])
    assert len(crb_batch.signatures) == 1


@pytest.mark.parametrize(
    ("q", "normal", "velocity", "restitution", "error", "message"),
    [
        (None, [0.0, 0.0, 0.0], [0.1, 0.0, 0.0], 0.0, BadInputError, "the surface normal must be non-zero"),
        (None, [np.nan, 0.0, 1.0], [0.1, 0.0, 0.0], 0.0, BadInputError, "the surface normal must be finite"),
        (None, [1.0, 0.0, 0.0], [np.inf, 0.0, 0.0], 0.0, BadInputError, "pre-impact contact velocity"),
        (None, [1.0, 0.0, 0.0], [0.1, 0.0], 0.0, BadInputError, "pre-impact contact velocity"),
        (None, [1.0, 0.0, 0.0], [0.1, 0.0, 0.0], 1.5, BadInputError, r"\[0, 1\]"),
        (None, [1.0, 0.0, 0.0], [0.1, 0.0, 0.0], True, BadInputError, "restitution"),
        ([0.0] * 6, [1.0, 0.0, 0.0], [0.1, 0.0, 0.0], 0.0, InvalidStateError, "7 values"),
        ([np.nan] * 7, [1.0, 0.0, 0.0], [0.1, 0.0, 0.0], 0.0, InvalidStateError, "non-finite"),
        ([4.0] * 7, [1.0, 0.0, 0.0], [0.1, 0.0, 0.0], 0.0, InvalidStateError, "outside the joint limits"),
    ],
)
def test_bad_input_gets_the_general_paths_error(q, normal, velocity, restitution, error, message):
    fast = predictor("panda")
    q = fast.robot.description.postures["elbow_up"].q if q is None else q
    with pytest.raises(error, match=message):
        fast.predict(q, normal, velocity, restitution)


def test_a_singular_posture_is_refused_and_the_batch_checks_its_inputs():
    fast = predictor("panda")
    with pytest.raises(SingularPostureError):
        fast.predict(SINGULAR_Q, [1.0, 0.0, 0.0], [-0.1, 0.0, 0.0], 0.0)
    with pytest.raises(BadInputError, match="shape"):
        fast.predict_batch(np.zeros((2, 6)), [1.0, 0.0, 0.0], [-0.1, 0.0, 0.0])
    with pytest.raises(BadInputError, match="non-finite"):
        fast.predict_batch(np.full((2, 7), np.nan), [1.0, 0.0, 0.0], [-0.1, 0.0, 0.0])
    with pytest.raises(BadInputError, match="normals"):
        fast.predict_batch(np.zeros((2, 7)), [0.0, 0.0, 0.0], [-0.1, 0.0, 0.0])


def test_a_floating_base_has_no_compiled_pass():
    with pytest.raises(ValueError, match="fixed-base"):
        KinematicTree(RobotModel("g1"))


def test_the_packed_tree_unpacks_to_the_tree():
    """``pack_tree``'s one array (what ``predict``'s kernel reads in one argument) gives back each
    field of the tree, for robots of different sizes and contact joints."""
    for name in ("panda", "ur5"):
        tree = CrbPredictor(RobotModel(name)).tree
        unpacked = unpacked_tree(pack_tree(tree))
        np.testing.assert_array_equal(unpacked[0], tree[0])
        assert unpacked[1] == tree[1] and unpacked[5] == tree[5]
        for ours, theirs in zip(unpacked[2:5], tree[2:5]):
            np.testing.assert_array_equal(ours, theirs)
