"""ImpactQuery validation and the JSON report of all predictors."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.prediction import FRICTIONAL_METHODS, ImpactQuery, inverse_inertia, predict_all


def test_query_builds_the_pre_impact_velocity():
    q = PANDA.postures["elbow_up"].q
    query = ImpactQuery.from_speed(q, [-2.0, 0, 0], 0.1, [0, 0.03, 0], 0.5)
    np.testing.assert_allclose(query.normal, [-1, 0, 0])
    np.testing.assert_allclose(query.pre_impact_velocity, [0.1, 0.03, 0])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"normal": [0, 0, 0]}, "zero"),
        ({"speed": 0.0}, r"\(0, 3\] m/s"),
        ({"speed": -1.0}, r"\(0, 3\] m/s"),
        ({"speed": float("nan")}, r"\(0, 3\] m/s"),
        ({"restitution": 1.5}, r"\[0, 1\]"),
        ({"restitution": -0.1}, r"\[0, 1\]"),
        ({"tangential": [0.1, 0, 0]}, "orthogonal"),
        ({"normal": [1, 0]}, "3 numbers"),
        ({"friction": -0.1}, "friction coefficient --friction"),
        ({"friction": 0.3, "restitution_model": "elastic"}, "restitution model"),
    ],
)
def test_bad_queries_are_rejected(kwargs, message):
    args = {"q": PANDA.postures["elbow_up"].q, "normal": [-1, 0, 0], "speed": 0.1, "tangential": None, "restitution": 0.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        ImpactQuery.from_speed(**args)


def test_report_has_the_contract_keys(robot):
    p = PANDA.postures["elbow_left"]
    report = predict_all(ImpactQuery.from_speed(p.q, p.surface.normal, 0.12), METHODS, robot)
    assert set(report) == {"q", "contact_point", "normal", "pre_impact_velocity", "restitution", "cond_M", "methods"}
    assert set(report["methods"]) == set(METHODS)
    for name, entry in report["methods"].items():
        assert len(entry["dq_jump"]) == JOINTS and len(entry["impulse"]) == 3
        assert ("W" in entry) == (name in ("gm", "crb"))
        expected = JUMP_MODELS[name].predict(robot.terms(p.q), p.surface.normal, -0.12 * p.surface.normal, 0.0)
        np.testing.assert_allclose(entry["dq_jump"], expected.dq_jump)
    assert report["cond_M"] == pytest.approx(np.linalg.cond(robot.terms(p.q).M))


@settings(max_examples=30)
@given(st.sampled_from(list(PANDA.postures)), st.floats(0.02, 1.0), st.floats(0.0, 0.1), st.floats(0.0, 1.0))
def test_a_frictional_prediction_is_the_predictors_map_of_the_frictional_impulse(posture, mu, tangential, restitution):
    """With friction each predictor's jump is its own map of the 3-D impulse (J ddq = W iota for
    CRB and GM: the contact velocity changes by W iota), the impulse lies in the friction cone,
    and with mu = 0 the CRB and GM reports are the frictionless ones (eq. (12))."""
    from impactqp.controller.model.frictional_impact import contact_frame

    robot = PandaModel()
    p = PANDA.postures[posture]
    n = p.surface.normal
    t = contact_frame(n)[:, 0]
    query = ImpactQuery.from_speed(p.q, n, 0.12, tangential * t, restitution, friction=mu)
    report = predict_all(query, METHODS, robot)
    assert set(report["methods"]) == set(FRICTIONAL_METHODS) and report["friction"] == mu
    terms = robot.terms(p.q)
    for name, entry in report["methods"].items():
        impulse = np.array(entry["impulse"])
        normal = impulse @ n
        assert normal > 0 and np.linalg.norm(impulse - normal * n) <= mu * normal * (1 + 1e-9)
        if name in ("crb", "gm"):
            W = np.array(entry["W"])
            np.testing.assert_allclose(terms.J @ entry["dq_jump"], W @ impulse, rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(entry["post_impact_contact_velocity"], query.pre_impact_velocity + W @ impulse,
                                       rtol=1e-9, atol=1e-12)
    frictionless = predict_all(ImpactQuery.from_speed(p.q, n, 0.12, None, restitution, friction=0.0), ("crb", "gm"), robot)
    plain = predict_all(ImpactQuery.from_speed(p.q, n, 0.12, None, restitution), ("crb", "gm"), robot)
    for name in ("crb", "gm"):
        np.testing.assert_allclose(frictionless["methods"][name]["dq_jump"], plain["methods"][name]["dq_jump"], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("method", FRICTIONAL_METHODS)
def test_inverse_inertia_is_the_predictors_own_or_the_classical_j_minv_jt(method):
    """The classical law's W is J M^-1 J^T; CRB's and GM's are their maps' own W; every W is an
    inverse inertia (symmetric positive definite)."""
    robot = PandaModel()
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    normal = np.array([-1.0, 0.0, 0.0])
    W = inverse_inertia(method, terms, normal)
    own = JUMP_MODELS[method].maps(terms, normal, 0.0).W
    expected = terms.J @ np.linalg.solve(terms.M, terms.J.T) if own is None else own
    np.testing.assert_allclose(W, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(W, W.T, atol=1e-10)
    assert np.all(np.linalg.eigvalsh(0.5 * (W + W.T)) > 0.0)


@settings(max_examples=15, deadline=None)
@given(st.sampled_from(["parallel", "staggered"]), st.floats(0.02, 1.0), st.floats(0.0, 0.2), st.floats(0.0, 1.0),
       st.sampled_from(["energetic", "kinematic"]))
def test_a_frictional_prediction_on_held_contacts_keeps_the_feet_still_and_moves_the_contact_by_w_iota(
        stance, mu, tangential, restitution, law):
    """The standing G1 (feet held): each predictor's jump of the frictional impulse keeps the held
    contacts still (Jf dv = 0), moves the hand's contact by W iota (the held-contact W of its
    maps: the frictional law's post-impact velocity), the impulse lies in the cone, and with
    mu = 0 CRB and GM give their frictionless (eq. 12) jumps."""
    from conftest import g1_model
    from impactqp.controller.model.humanoid_stance import stance_posture
    from impactqp.controller.model.prediction import method_prediction

    robot = g1_model()
    terms = robot.terms(stance_posture(robot, robot.description.stances[stance]))
    n = np.array([-1.0, 0.0, 0.0])
    query = ImpactQuery.from_speed(terms.q, n, 0.5, [0.0, tangential, 0.0], restitution, mu, law)
    for name in ("classical", "gm", "crb"):
        pred, impact = method_prediction(name, terms, query)
        W = inverse_inertia(name, terms, n, restitution)
        scale = np.linalg.norm(W @ pred.impulse)
        np.testing.assert_allclose(terms.held_jacobian @ pred.dq_jump, 0.0, atol=1e-9 * max(scale, 1.0))
        np.testing.assert_allclose(terms.J @ pred.dq_jump, W @ pred.impulse, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(impact.post_velocity, query.pre_impact_velocity + W @ pred.impulse, rtol=1e-8, atol=1e-10)
        normal = pred.impulse @ n
        assert normal > 0 and np.linalg.norm(pred.impulse - normal * n) <= mu * normal * (1 + 1e-9)
        np.testing.assert_allclose(pred.com_jump, terms.Jcom @ pred.dq_jump, rtol=1e-12, atol=1e-15)
    frictionless = ImpactQuery.from_speed(terms.q, n, 0.5, None, restitution, 0.0)
    for name in ("crb", "gm"):
        plain = JUMP_MODELS[name].predict(terms, n, frictionless.pre_impact_velocity, restitution)
        np.testing.assert_allclose(method_prediction(name, terms, frictionless)[0].dq_jump, plain.dq_jump,
                                   rtol=1e-12, atol=1e-12)
