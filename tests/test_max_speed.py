"""The closed-form highest feasible contact speed (docs/max-speed.md)."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import JUMP_MODELS
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.max_speed import (
    CRITERIA,
    approach_direction,
    closed_form_max_speed,
    closed_form_max_speeds,
    criterion_slopes,
)
from impactqp.controller.model.robot_description import PANDA


def criteria_ratios(robot, terms, normal, model, speed, restitution=0.0, impact_duration=0.015):
    """Largest limit ratio of each criterion, evaluated directly from the predictor at speed v."""
    dq_minus = speed * approach_direction(terms, normal)
    pred = model.predict(terms, normal, terms.J @ dq_minus, restitution)
    return {
        "velocity_pre": np.max(np.abs(dq_minus) / robot.dq_max),
        "velocity_post": np.max(np.abs(dq_minus + pred.dq_jump) / robot.dq_max),
        "impulsive_torque": np.max(np.abs(terms.J.T @ pred.impulse) / impact_duration / robot.tau_max),
    }


@pytest.mark.parametrize("name", list(PANDA.postures))
@pytest.mark.parametrize("method", ["classical", "gm", "crb"])
@pytest.mark.parametrize("restitution", [0.0, 0.6])
def test_max_speed_is_where_the_first_criterion_reaches_its_limit(robot, name, method, restitution):
    p = PANDA.postures[name]
    terms = robot.terms(p.q)
    n, model = p.surface.normal, JUMP_MODELS[method]
    best = closed_form_max_speed(robot, terms, n, model, restitution)
    at = criteria_ratios(robot, terms, n, model, best.speed, restitution)
    assert at[best.criterion] == pytest.approx(1.0, rel=1e-9)
    assert max(at.values()) == pytest.approx(1.0, rel=1e-9)
    assert max(criteria_ratios(robot, terms, n, model, 0.999 * best.speed, restitution).values()) < 1.0
    assert max(criteria_ratios(robot, terms, n, model, 1.001 * best.speed, restitution).values()) > 1.0
    assert 1 <= best.joint <= JOINTS


def test_approach_translates_without_rotating(robot):
    p = PANDA.postures["elbow_left"]
    terms = robot.terms(p.q)
    twist = terms.J6 @ approach_direction(terms, p.surface.normal)
    np.testing.assert_allclose(twist, np.concatenate([-p.surface.normal, np.zeros(3)]), atol=1e-10)


def test_longer_impacts_allow_higher_speeds(robot):
    p = PANDA.postures["elbow_up"]
    terms = robot.terms(p.q)
    short = closed_form_max_speed(robot, terms, p.surface.normal, JUMP_MODELS["crb"], impact_duration=0.005)
    long = closed_form_max_speed(robot, terms, p.surface.normal, JUMP_MODELS["crb"], impact_duration=0.05)
    assert short.speed <= long.speed


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**31), restitution=st.floats(0.0, 1.0), impact_duration=st.floats(0.002, 0.05))
def test_the_batched_closed_form_equals_the_one_posture_closed_form(robot, seed, restitution, impact_duration):
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.q_min + 0.1, robot.q_max - 0.1, (12, JOINTS))
    normals = rng.normal(size=(12, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    terms = BatchKinematics(robot).terms(Q)
    for name, model in JUMP_MODELS.items():
        batch = closed_form_max_speeds(robot, terms, normals, name, restitution, impact_duration)
        for i, q in enumerate(Q):
            terms_i = robot.terms(q)
            one = closed_form_max_speed(robot, terms_i, normals[i], model, restitution, impact_duration)
            assert batch.speed[i] == pytest.approx(one.speed, rel=1e-9)
            # what binds is the same, or binds at the same speed (a tie to rounding)
            slopes = criterion_slopes(robot, terms_i, normals[i], model, restitution, impact_duration)
            assert 1.0 / slopes[CRITERIA[batch.criterion[i]]][batch.joint[i] - 1] == pytest.approx(one.speed, rel=1e-9)


ROBOT_TOOLS = [("panda", "impact_tip"), ("fr3", "impact_tip"), ("fr3", "franka_hand"), ("panda", "pad")]


@pytest.mark.parametrize("robot_name, tool", ROBOT_TOOLS)
@pytest.mark.parametrize("jump_model", ["crb", "gm"])
def test_the_qp_settles_at_the_closed_form_speed_of_each_robot(robot_name, tool, jump_model):
    """Asked for 2 m/s at a fixed elbow_up posture (solved for the tool), the wall 5 cm ahead and
    the impact-aware rows always on, the QP's commanded contact speed settles at the closed-form
    maximum of the same jump model and that robot's own limits: the QP and the closed form
    agree on every robot, not only on the Panda."""
    from impactqp.controller.config import ControllerConfig, build_controller
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.controller.model.postures import Surface

    choice = RobotChoice.of(robot_name, tool)
    robot, posture = choice.model(), choice.posture("elbow_up")
    q, normal = posture.q, posture.surface.normal
    surface = Surface(robot.contact_point(q) - 0.05 * normal, normal)
    config = ControllerConfig.approach(
        surface, speed=2.0, jump_model=jump_model, always_active=True, posture_weight=0.0
    )
    controller = build_controller(config, robot)
    dq = np.zeros(JOINTS)
    for _ in range(800):
        dq = controller.step(q, dq).dq_cmd
    terms = robot.terms(q)
    closed_form = closed_form_max_speed(robot, terms, normal, JUMP_MODELS[jump_model])
    assert float(-normal @ (terms.J @ dq)) == pytest.approx(closed_form.speed, rel=0.01)
    np.testing.assert_array_equal(robot.dq_max, choice.robot.dq_max)
