"""The vectorised batch API equals the one-state path."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import JOINTS, unit_vectors
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.batch import BatchKinematics, predict_batch
from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.validation import BadInputError


@pytest.fixture(scope="module")
def kinematics(robot):
    return BatchKinematics(robot)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31), n=unit_vectors(), cr=st.floats(0.0, 1.0))
def test_batch_equals_single_state_predictions(robot, kinematics, seed, n, cr):
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.q_min + 0.1, robot.q_max - 0.1, (20, JOINTS))
    v_minus = -0.15 * n + 0.04 * np.cross(n, [0.0, 0.0, 1.0])
    for method in METHODS:
        dq, impulse = predict_batch(kinematics, Q, n, v_minus, cr, method)
        for i, q in enumerate(Q):
            pred = JUMP_MODELS[method].predict(robot.terms(q), n, v_minus, cr)
            np.testing.assert_allclose(dq[i], pred.dq_jump, rtol=1e-8, atol=1e-10)
            np.testing.assert_allclose(impulse[i], pred.impulse, rtol=1e-8, atol=1e-10)


def test_batch_terms_match_pinocchio(robot, kinematics):
    Q = np.random.default_rng(1).uniform(robot.q_min, robot.q_max, (10, JOINTS))
    terms = kinematics.terms(Q)
    data = robot.model.createData()
    for i, q in enumerate(Q):
        np.testing.assert_allclose(terms.M[i], pin.crba(robot.model, data, q), atol=1e-10)
        ref = robot.terms(q, check_limits=False)
        np.testing.assert_allclose(terms.J[i], ref.J, atol=1e-12)
        np.testing.assert_allclose(terms.com[i], ref.com, atol=1e-12)
        np.testing.assert_allclose(terms.inertia_com[i], ref.inertia_com, atol=1e-12)


def test_batch_contact_frames_match_pinocchio(robot, kinematics):
    Q = np.random.default_rng(2).uniform(robot.q_min, robot.q_max, (10, JOINTS))
    points, axes, J6 = kinematics.contact_frames(Q)
    for i, q in enumerate(Q):
        frame = robot.contact_frame(q)
        np.testing.assert_allclose(points[i], frame.translation, atol=1e-12)
        np.testing.assert_allclose(axes[i], frame.rotation[:, 2], atol=1e-12)
        np.testing.assert_allclose(J6[i], robot.contact_jacobian6(q), atol=1e-12)


def test_batch_with_measured_impulses(robot, kinematics):
    Q = np.random.default_rng(2).uniform(robot.q_min + 0.1, robot.q_max - 0.1, (5, JOINTS))
    impulses = np.random.default_rng(3).normal(size=(5, 3))
    n = np.array([-1.0, 0.0, 0.0])
    for method in METHODS:
        dq, used = predict_batch(kinematics, Q, n, -0.1 * n, 0.0, method, impulses=impulses)
        np.testing.assert_array_equal(used, impulses)
        for i, q in enumerate(Q):
            expected = JUMP_MODELS[method].predict(robot.terms(q), n, -0.1 * n, 0.0, impulse=impulses[i])
            np.testing.assert_allclose(dq[i], expected.dq_jump, rtol=1e-8, atol=1e-10)


def test_batch_rejects_bad_input(kinematics):
    with pytest.raises(ValueError, match="shape"):
        kinematics.terms(np.zeros((3, 6)))
    with pytest.raises(ValueError, match="non-finite"):
        kinematics.terms(np.full((2, JOINTS), np.nan))
    with pytest.raises(ValueError, match="unknown method"):
        predict_batch(kinematics, np.zeros((1, JOINTS)), [1, 0, 0], [-1, 0, 0], 0.0, "magic")


def test_batch_refuses_bad_normals_and_restitution_like_the_single_state_predictors(kinematics):
    q = np.zeros((2, JOINTS))
    for normals in ([0.0, 0.0, 0.0], [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [np.nan, 0.0, 1.0], [1.0, 0.0]):
        with pytest.raises(BadInputError, match="normals"):
            predict_batch(kinematics, q, normals, [-0.1, 0, 0], 0.0, "crb")
    for restitution in (-0.1, 1.5, float("nan")):
        with pytest.raises(BadInputError, match=r"\[0, 1\]"):
            predict_batch(kinematics, q, [1.0, 0, 0], [-0.1, 0, 0], restitution, "gm")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    "argument, value, match",
    [
        ("velocities", [np.nan, 0.0, 0.0], "pre-impact velocities must be finite"),
        ("velocities", np.zeros((3, 3)), r"pre-impact velocities must be \(3,\) or \(2, 3\)"),
        ("velocities", ["a", "b", "c"], "pre-impact velocities must hold real numbers"),
        ("normals", [[1.0, 0.0, 0.0]] * 3, r"normals must be \(3,\) or \(2, 3\)"),
        ("impulses", [np.inf, 0.0, 0.0], "impulses must be finite"),
        ("impulses", [1.0, 0.0], r"impulses must be \(3,\) or \(2, 3\)"),
        ("Q", np.full((2, JOINTS), 0.1 + 0.1j), "Q must hold real numbers"),
        ("Q", np.full((2, JOINTS), np.nan), "Q contains a non-finite value"),
    ],
)
def test_every_batch_input_is_checked_before_any_prediction(kinematics, method, argument, value, match):
    inputs = {"Q": np.zeros((2, JOINTS)), "normals": [1.0, 0.0, 0.0], "velocities": [-0.1, 0.0, 0.0], "impulses": None}
    inputs[argument] = value
    with pytest.raises(BadInputError, match=match):
        predict_batch(kinematics, inputs["Q"], inputs["normals"], inputs["velocities"], 0.0, method, inputs["impulses"])


def test_rows_of_batch_terms_equal_the_terms_of_those_states(robot):
    """Selecting states from evaluated terms gives what evaluating those states gives."""
    kinematics = BatchKinematics(robot)
    Q = np.random.default_rng(3).uniform(robot.q_min, robot.q_max, (6, JOINTS))
    terms = kinematics.terms(Q)
    terms.M  # computed before the selection: it comes along
    keep = np.array([True, False, True, True, False, True])
    subset, direct = terms.rows(keep), kinematics.terms(Q[keep])
    for name in ("J", "contact_point", "com", "inertia_com", "joint_axes", "joint_origins", "link_com", "M"):
        np.testing.assert_allclose(getattr(subset, name), getattr(direct, name), rtol=1e-12, atol=1e-12)
    assert subset.mass == direct.mass
