"""ImpactQuery validation and the JSON report of all predictors."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.prediction import ImpactQuery, predict_all


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
