"""An arm's highest speed under the robust friction rows (controller/model/friction_max_speed.py;
docs/frictional-impacts.md): the frictionless closed form at zero friction, never higher with
friction, and the frictional impulse at the answer inside the cone and within the limits."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS, g1_model
from impactqp.constraints import ExpectedImpact
from impactqp.controller.model.friction_pyramid import FrictionRows, response_maps
from impactqp.controller.model.frictional_impact import contact_frame, frictional_impulse
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.max_speed import Setting, closed_form_max_speed
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError

FRICTION_POSTURES = list(PANDA.postures)


def tangential_of(normal, a, b):
    frame = contact_frame(normal)
    return a * frame[:, 0] + b * frame[:, 1]


@pytest.mark.parametrize("name", FRICTION_POSTURES)
@pytest.mark.parametrize("method", ["crb", "gm", "classical"])
def test_zero_friction_without_sliding_is_the_frictionless_closed_form(robot, name, method):
    posture = PANDA.postures[name]
    terms, setting = robot.terms(posture.q), Setting(method, 0.3)
    frictionless = closed_form_max_speed(robot, terms, posture.surface.normal, setting)
    zero = frictional_max_speed(robot, terms, posture.surface.normal, np.zeros(3), setting, FrictionRows(0.0))
    assert zero.max_speed.speed == pytest.approx(frictionless.speed, rel=1e-12)
    assert (zero.max_speed.criterion, zero.max_speed.joint) == (frictionless.criterion, frictionless.joint)
    assert zero.block in ("frictionless", "")


@settings(max_examples=20)
@given(st.sampled_from(FRICTION_POSTURES), st.sampled_from(["crb", "gm", "classical"]), st.floats(0.01, 2.0),
       st.integers(3, 16), st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.sampled_from(["pyramid", "slip"]))
def test_friction_never_raises_the_highest_speed_and_the_bound_binds(robot, name, method, mu, k, a, b, mode):
    """Friction adds rows: its highest speed is at most the frictionless one at the same
    tangential velocity, and at that speed every row holds with one at its limit."""
    posture = PANDA.postures[name]
    normal, terms, setting = posture.surface.normal, robot.terms(posture.q), Setting(method, 0.2)
    tangential = tangential_of(normal, a, b)
    without = frictional_max_speed(robot, terms, normal, tangential, setting, FrictionRows(0.0))
    answer = frictional_max_speed(robot, terms, normal, tangential, setting, FrictionRows(mu, k, mode))
    v = answer.max_speed.speed
    assert v <= without.max_speed.speed * (1 + 1e-12)
    if not 0.0 < v < math.inf:
        return
    dq_pre = np.linalg.pinv(terms.J6) @ np.concatenate([tangential - v * normal, np.zeros(3)])
    rows = ExpectedImpact(Surface(terms.contact_point, normal), method, 0.2, friction=FrictionRows(mu, k, mode))
    frozen = robot.terms(posture.q, dq_pre if mode == "slip" else np.zeros(JOINTS))  # the preview reads dq
    edges = rows.edge_matrices(frozen)
    own = rows.matrices(frozen)
    worst = 0.0
    for A, P in [(own.jump_matrix, own.torque_matrix), *zip(edges.jump, edges.torque)]:
        worst = max(worst, np.max(np.abs(dq_pre + A @ dq_pre) / robot.dq_max),
                    np.max(np.abs(P @ dq_pre) / setting.duration(robot.description) / robot.tau_max))
    worst = max(worst, np.max(np.abs(dq_pre) / robot.dq_max))
    assert worst == pytest.approx(1.0, rel=1e-9)


@settings(max_examples=25)
@given(st.sampled_from(FRICTION_POSTURES), st.sampled_from(["crb", "gm", "classical"]), st.floats(0.02, 1.0),
       st.integers(3, 12), st.floats(-0.15, 0.15), st.floats(-0.15, 0.15), st.sampled_from(["energetic", "kinematic"]),
       st.sampled_from(["pyramid", "slip"]))
def test_the_frictional_impulse_at_the_rows_speed_is_in_the_cone_and_keeps_the_limits(robot, name, method, mu, k, a, b, law, mode):
    """Without restitution, the rows, whose pyramid circumscribes the cone (mu / cos(pi / k)), cover
    the frictional impulse of any mode (docs/frictional-impacts.md: the impulse that ends
    compression along n + tau is a perspective image of tau, which maps the pyramid's section
    onto the hull of the edge impulses): at the rows' highest speed, ``frictional_impulse``'s
    impulse lies in the cone and its post-impact velocity and impulsive torque keep the limits.
    The preview's rows too: its sector's edges circumscribe the sector's arc, where a certain slip
    keeps the impulse, and its 3-edge pyramid the whole cone."""
    posture = PANDA.postures[name]
    normal, terms, setting = posture.surface.normal, robot.terms(posture.q), Setting(method, 0.0)
    tangential = tangential_of(normal, a, b)
    rows = FrictionRows(mu, k, mode)
    v = frictional_max_speed(robot, terms, normal, tangential, setting, rows).max_speed.speed
    if not 0.0 < v < math.inf:
        return
    K, W = response_maps(JUMP_MODELS[method], terms, normal, 0.0)
    impact = frictional_impulse(W, normal, tangential - v * normal, mu, 0.0, law)
    iota = impact.impulse
    normal_part = normal @ iota
    assert np.linalg.norm(iota - normal_part * normal) <= mu * normal_part * (1 + 1e-9)
    dq_pre = np.linalg.pinv(terms.J6) @ np.concatenate([tangential - v * normal, np.zeros(3)])
    assert np.all(np.abs(dq_pre + K @ iota) <= robot.dq_max * (1 + 1e-6))
    assert np.all(np.abs(terms.J.T @ iota) / setting.duration(robot.description) <= robot.tau_max * (1 + 1e-6))


def test_the_frictional_closed_form_reports_the_contact_mode(robot):
    posture = PANDA.postures["elbow_up"]
    normal, terms = posture.surface.normal, robot.terms(posture.q)
    sliding = frictional_max_speed(robot, terms, normal, tangential_of(normal, 0.1, 0.0), Setting(), FrictionRows(0.05))
    assert sliding.mode == "slip"  # mu far below mu_bar, a fast slide: it never stops
    assert sliding.mu_bar > 0.05
    sticking = frictional_max_speed(robot, terms, normal, np.zeros(3), Setting(), FrictionRows(sliding.mu_bar * 1.5))
    assert sticking.mode == "stick"


def test_the_frictional_closed_form_is_an_arms():
    g1 = g1_model()
    terms = g1.terms(stance_posture(g1, STANCES["parallel"]))
    with pytest.raises(BadInputError, match="held contacts"):
        frictional_max_speed(g1, terms, np.array([-1.0, 0.0, 0.0]), np.zeros(3), Setting(), FrictionRows(0.2))
