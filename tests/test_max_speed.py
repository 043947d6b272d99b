"""The closed-form highest feasible contact speed of every robot (controller/model/max_speed.py;
docs/max-speed.md, docs/floating-base.md): an arm's joint criteria, and a standing G1's joint and
held-contact criteria."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from whole_body_states import criterion_margins
from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.capture import capturable_speeds, max_capturable_speed, support_capture_region
from impactqp.controller.model.jump import predict
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import STANCES, convex_hull, inside_polygon, stance_posture
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.max_speed import (
    CRITERIA,
    HAND_IMPACT_DURATION,
    HELD_CONTACT_CRITERIA,
    Setting,
    approach_direction,
    closed_form_max_speed,
    closed_form_max_speeds,
    cone_step,
    criteria_of,
    criterion_slopes,
    joint_bound,
    joint_velocity_ratio,
    sole_rows,
    standing_wrenches,
    unit_impact,
)
from impactqp.controller.model.robot_description import PANDA, ROBOTS
from impactqp.controller.model.validation import BadInputError


def criteria_ratios(robot, terms, normal, model, speed, restitution=0.0, impact_duration=0.015):
    """Largest limit ratio of each criterion, evaluated directly from the predictor at speed v."""
    dq_minus = speed * approach_direction(robot, terms, normal)
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
    best = closed_form_max_speed(robot, terms, n, Setting(method, restitution))
    at = criteria_ratios(robot, terms, n, model, best.speed, restitution)
    assert at[best.criterion] == pytest.approx(1.0, rel=1e-9)
    assert max(at.values()) == pytest.approx(1.0, rel=1e-9)
    assert max(criteria_ratios(robot, terms, n, model, 0.999 * best.speed, restitution).values()) < 1.0
    assert max(criteria_ratios(robot, terms, n, model, 1.001 * best.speed, restitution).values()) > 1.0
    assert 1 <= best.joint <= JOINTS and best.where == robot.description.joints[best.joint - 1]
    assert set(best.bounds) == set(CRITERIA) == set(criteria_of(robot.description))


def test_approach_translates_without_rotating(robot):
    p = PANDA.postures["elbow_left"]
    terms = robot.terms(p.q)
    twist = terms.J6 @ approach_direction(robot, terms, p.surface.normal)
    np.testing.assert_allclose(twist, np.concatenate([-p.surface.normal, np.zeros(3)]), atol=1e-10)


@settings(max_examples=20, deadline=None)
@given(scale=st.floats(1e-3, 1e3), name=st.sampled_from(list(PANDA.postures)))
def test_the_speed_does_not_depend_on_the_length_of_the_normal(robot, scale, name):
    p = PANDA.postures[name]
    terms = robot.terms(p.q)
    unit = closed_form_max_speed(robot, terms, p.surface.normal, Setting("crb"))
    scaled = closed_form_max_speed(robot, terms, scale * p.surface.normal, Setting("crb"))
    assert scaled.speed == pytest.approx(unit.speed, rel=1e-12) and scaled.criterion == unit.criterion


@pytest.mark.parametrize(
    "normal, setting, match",
    [
        ([-1.0, 0.0], Setting(), "normal"),
        ([0.0, 0.0, 0.0], Setting(), "normal"),
        ([np.nan, 0.0, 1.0], Setting(), "normal"),
    ],
)
def test_a_bad_normal_is_bad_input(robot, normal, setting, match):
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    with pytest.raises(BadInputError, match=match):
        closed_form_max_speed(robot, terms, normal, setting)


@pytest.mark.parametrize(
    "options, match",
    [
        ({"restitution": 1.5}, "restitution"),
        ({"restitution": float("nan")}, "restitution"),
        ({"impact_duration": 1e9}, "impact duration"),
        ({"impact_duration": 0.0}, "impact duration"),
        ({"friction": -0.1}, "friction"),
        ({"friction": float("inf")}, "friction"),
    ],
)
def test_a_setting_out_of_its_ranges_is_bad_input(options, match):
    with pytest.raises(BadInputError, match=match):
        Setting(**options)


def test_longer_impacts_allow_higher_speeds(robot):
    p = PANDA.postures["elbow_up"]
    terms = robot.terms(p.q)
    short = closed_form_max_speed(robot, terms, p.surface.normal, Setting(impact_duration=0.005))
    long = closed_form_max_speed(robot, terms, p.surface.normal, Setting(impact_duration=0.05))
    assert short.speed <= long.speed


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**31), restitution=st.floats(0.0, 1.0), impact_duration=st.floats(0.002, 0.05))
def test_the_batched_closed_form_equals_the_one_posture_closed_form(robot, seed, restitution, impact_duration):
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.q_min + 0.1, robot.q_max - 0.1, (12, JOINTS))
    normals = rng.normal(size=(12, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    terms = BatchKinematics(robot).terms(Q)
    for name in JUMP_MODELS:
        batch = closed_form_max_speeds(robot, terms, normals, name, restitution, impact_duration)
        setting = Setting(name, restitution, impact_duration=impact_duration)
        for i, q in enumerate(Q):
            terms_i = robot.terms(q)
            one = closed_form_max_speed(robot, terms_i, normals[i], setting)
            assert batch.speed[i] == pytest.approx(one.speed, rel=1e-9)
            # what binds is the same, or binds at the same speed (a tie to rounding)
            slopes = criterion_slopes(robot, terms_i, normals[i], setting)
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
    closed_form = closed_form_max_speed(robot, terms, normal, Setting(jump_model))
    assert float(-normal @ (terms.J @ dq)) == pytest.approx(closed_form.speed, rel=0.01)
    np.testing.assert_array_equal(robot.dq_max, choice.robot.dq_max)


# ---------------------------------------------------------------- a robot with held contacts: the G1
NORMAL = np.array([-1.0, 0.0, 0.0])
FOOT = ROBOTS["g1"].held_contacts[0]
SOLE, SOLE_DEPTH = convex_hull(FOOT.sole), FOOT.depth
vectors = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(lambda v: np.round(v, 6))  # no 1e-300 slopes


@pytest.fixture(scope="module")
def g1():
    return RobotModel("g1")


@pytest.fixture(scope="module", params=["parallel", "staggered", "step"])
def stance_q(request, g1):
    return stance_posture(g1, STANCES[request.param])


@settings(max_examples=80, deadline=None)
@given(vectors, vectors, st.floats(0.2, 2.0))
def test_cone_step_ends_on_the_cone_and_stays_inside_before(force0, force1, mu):
    force0 = force0.copy()
    force0[2] = np.linalg.norm(force0[:2]) / mu + abs(force0[2]) + 0.1  # inside the cone at s = 0
    s = cone_step(force0, force1, mu)
    for t in np.linspace(0.0, min(s, 1e3), 7)[:-1]:
        f = force0 + t * force1
        assert np.linalg.norm(f[:2]) <= mu * f[2] + 1e-9 * (1 + np.abs(f).sum())
    if math.isfinite(s):
        f = force0 + s * force1
        assert np.linalg.norm(f[:2]) == pytest.approx(mu * f[2], abs=1e-6 * (1 + np.abs(f).sum()))


@settings(max_examples=80, deadline=None)
@given(st.floats(-0.1, 0.15), st.floats(-0.05, 0.05), st.floats(0.1, 100.0), vectors)
def test_sole_rows_hold_exactly_when_a_point_force_lies_inside_the_sole(x, y, fz, tangent):
    """A force (t_x, t_y, fz) applied at the sole point (x, y): the rows are <= 0 iff (x, y) is in the sole."""
    f = np.array([tangent[0], tangent[1], fz])
    point = np.array([x, y, -SOLE_DEPTH])  # in the foot frame
    wrench = np.concatenate([f, np.cross(point, f)])
    inside = inside_polygon([x, y], SOLE)
    rows = sole_rows(SOLE, SOLE_DEPTH, wrench) / fz
    if inside > 1e-9:
        assert np.all(rows < 0.0)
    elif inside < -1e-9:
        assert np.any(rows > 0.0)


def test_the_bound_is_the_smallest_criterion_and_every_criterion_is_met_up_to_it(g1, stance_q):
    result = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL)
    assert set(result.bounds) == set(HELD_CONTACT_CRITERIA) == set(criteria_of(g1.description))
    assert result.speed == min(b.speed for b in result.bounds.values())
    assert result.bounds[result.criterion].speed == result.speed
    assert 0.0 < result.speed < math.inf


def test_joint_velocity_bound_puts_the_worst_joint_at_its_limit(g1, stance_q):
    terms = g1.terms(stance_q)
    d = approach_direction(g1, terms, NORMAL)
    np.testing.assert_allclose(terms.J @ d, -NORMAL, atol=1e-9)
    dv = predict(terms, "classical", NORMAL, terms.J @ d).dq_jump
    unit = unit_impact(g1, terms, NORMAL, Setting("classical"))
    np.testing.assert_array_equal(unit.jump, dv)
    bound = joint_bound(g1, joint_velocity_ratio(unit))
    s = bound.speed
    joints = slice(g1.base_nv, None)
    ratio = np.maximum(np.abs(s * d[joints]), np.abs(s * (d + dv)[joints])) / g1.dq_max
    assert ratio.max() == pytest.approx(1.0)
    assert g1.joint_names[int(np.argmax(ratio))] == bound.where


def test_standing_wrenches_carry_the_weight(g1, stance_q):
    terms = g1.terms(stance_q)
    w = standing_wrenches(g1, terms)
    assert w[2] + w[8] == pytest.approx(terms.mass * 9.81, rel=1e-6)
    assert w[2] > 0.0 and w[8] > 0.0


@pytest.mark.parametrize("method", ["classical", "crb"])
def test_foot_bounds_scale_with_the_contact_duration_and_the_rest_does_not(g1, stance_q, method):
    """F = T w + s lambda: doubling T doubles the foot bounds (both are homogeneous in (T, s))."""
    one = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL, Setting(method))
    two = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL, Setting(method, impact_duration=2 * HAND_IMPACT_DURATION))
    for criterion in ("foot_slip", "foot_lift"):
        assert two.bounds[criterion].speed == pytest.approx(2 * one.bounds[criterion].speed, rel=1e-9)
    for criterion in ("joint_velocity", "capture"):
        assert two.bounds[criterion].speed == pytest.approx(one.bounds[criterion].speed, rel=1e-12)


def test_more_friction_never_lowers_the_slip_bound(g1, stance_q):
    low = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL, Setting(friction=0.5))
    high = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL, replace(Setting(), friction=1.5))
    assert high.bounds["foot_slip"].speed >= low.bounds["foot_slip"].speed


def test_capture_bound_is_the_capture_modules(g1, stance_q):
    terms = g1.terms(stance_q)
    region = support_capture_region(g1, stance_q, terms.com)
    v1 = terms.J @ approach_direction(g1, terms, NORMAL)
    result = closed_form_max_speed(g1, g1.terms(stance_q), NORMAL)
    assert result.bounds["capture"].speed == pytest.approx(max_capturable_speed(terms, region, "crb", NORMAL, v1))
    edges = capturable_speeds(terms, region, "crb", NORMAL, v1)
    assert result.bounds["capture"].where == f"edge {int(np.argmin(edges))}"


def test_zero_friction_is_bad_input(g1, stance_q):
    with pytest.raises(BadInputError):
        closed_form_max_speed(g1, g1.terms(stance_q), NORMAL, Setting(friction=0.0))


def _criterion_margins(g1, q, speed, heights, setting=Setting()):
    """Each criterion's smallest margin at the contact speed ``speed`` along the closed form's
    approach, with the predictor's own impulse (``whole_body_states.criterion_margins``)."""
    terms = g1.terms(q)
    dq_pre = speed * approach_direction(g1, terms, NORMAL)
    jump = predict(terms, setting.method, NORMAL, terms.J @ dq_pre)
    return criterion_margins(q, dq_pre, jump, heights, setting.duration(g1.description))


@pytest.mark.parametrize("method", ["crb", "classical"])
def test_on_the_step_every_criterion_holds_at_the_closed_form_speed_and_the_binding_one_is_tight(g1, method):
    """The step stance (the left sole 10 cm up): at the closed form's speed every row holds and the
    binding criterion's is at its limit; 1 % faster it fails."""
    stance = STANCES["step"]
    q = stance_posture(g1, stance)
    heights = np.repeat(stance.heights, 4)
    best = closed_form_max_speed(g1, g1.terms(q), NORMAL, Setting(method))
    at = _criterion_margins(g1, q, best.speed, heights, Setting(method))
    assert min(at.values()) >= -1e-6
    assert at[best.criterion] == pytest.approx(0.0, abs=1e-6)
    assert _criterion_margins(g1, q, 1.01 * best.speed, heights, Setting(method))[best.criterion] < 0.0


@settings(max_examples=4, deadline=None)
@given(st.floats(-math.pi, math.pi))
def test_turning_the_whole_step_stance_about_the_vertical_keeps_the_highest_speed(g1, angle):
    """Frame invariance: the robot and the wall turned together about z give the same bounds."""
    import pinocchio as pin

    q = stance_posture(g1, STANCES["step"])
    turn = pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, angle), np.zeros(3))
    turned = q.copy()
    turned[:7] = pin.SE3ToXYZQUAT(turn * pin.XYZQUATToSE3(q[:7]))
    one = closed_form_max_speed(g1, g1.terms(q), NORMAL)
    other = closed_form_max_speed(g1, g1.terms(turned), turn.rotation @ NORMAL)
    for criterion, bound in one.bounds.items():
        assert other.bounds[criterion].speed == pytest.approx(bound.speed, rel=1e-9)
    assert (other.criterion, other.where) == (one.criterion, one.where)
