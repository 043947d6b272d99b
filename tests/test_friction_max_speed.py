"""An arm's highest speed under the robust friction rows (controller/model/friction_max_speed.py;
docs/frictional-impacts.md): the frictionless closed form at zero friction, never higher with
friction, and the frictional impulse at the answer inside the cone and within the limits."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from whole_body_states import NORMAL, criterion_margins, standing_states, vertex_impulses
from whole_body_states import robot as g1_robot
from impactqp.constraints import ExpectedImpact
from impactqp.controller.model.friction_pyramid import FrictionRows, held_response_maps, pyramid_directions, response_maps
from impactqp.controller.model.frictional_impact import contact_frame, frictional_impulse
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.max_speed import HAND_IMPACT_DURATION, Setting, closed_form_max_speed
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA

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


def rows_at(robot, posture, method, rows, tangential, v):
    """The QP's impact rows at the approach dq- moving the contact at v_t - v n, as
    ``ExpectedImpact`` builds them from that state (the preview reads its edges from dq): the
    largest ratio of a row to its limit (the pre- and post-impact velocities and the impulsive
    torque of the frictionless and every edge impulse) and a copy of the edges' maps."""
    normal, setting = posture.surface.normal, Setting(method, 0.2)
    terms = robot.terms(posture.q)
    dq_pre = np.linalg.pinv(terms.J6) @ np.concatenate([tangential - v * normal, np.zeros(3)])
    impact = ExpectedImpact(Surface(terms.contact_point, normal), method, 0.2, friction=rows)
    frozen = robot.terms(posture.q, dq_pre)
    edges, own = impact.edge_matrices(frozen), impact.matrices(frozen)
    worst = np.max(np.abs(dq_pre) / robot.dq_max)
    for A, P in [(own.jump_matrix, own.torque_matrix), *zip(edges.jump, edges.torque)]:
        worst = max(worst, np.max(np.abs(dq_pre + A @ dq_pre) / robot.dq_max),
                    np.max(np.abs(P @ dq_pre) / setting.duration(robot.description) / robot.tau_max))
    return worst, np.array(edges.jump)


@settings(max_examples=20)
@given(st.sampled_from(FRICTION_POSTURES), st.sampled_from(["crb", "gm", "classical"]), st.floats(0.01, 2.0),
       st.integers(3, 16), st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.sampled_from(["pyramid", "slip"]))
# the 3-edge pyramid's rows bind at 0.0101 m/s, below 0.0134, the highest speed of a certain slip, where the sector's hold
@example(name="elbow_left", method="crb", mu=0.5, k=3, a=0.0, b=0.1875, mode="slip")
def test_friction_never_raises_the_highest_speed_and_the_rows_hold_up_to_it(robot, name, method, mu, k, a, b, mode):
    """Friction adds rows: its highest speed v is at most the frictionless one at the same
    tangential velocity. It is the highest speed up to which the QP's rows, as built at each
    speed, hold: they hold at every slower speed (the preview's edges are read from that speed's
    dq-) and fail just faster. Where the rows just slower and just faster have the same edges
    (the rows are then one set of affine functions of v), one of them is at its limit at v; where
    the preview's edges change there (its slip certain below, not above), the faster rows fail."""
    posture = PANDA.postures[name]
    normal, terms, setting = posture.surface.normal, robot.terms(posture.q), Setting(method, 0.2)
    tangential = tangential_of(normal, a, b)
    rows = FrictionRows(mu, k, mode)
    without = frictional_max_speed(robot, terms, normal, tangential, setting, FrictionRows(0.0))
    v = frictional_max_speed(robot, terms, normal, tangential, setting, rows).max_speed.speed
    assert v <= without.max_speed.speed * (1 + 1e-12)
    if not 0.0 < v < math.inf:
        return
    for factor in (0.0, 0.25, 0.5, 0.75):
        assert rows_at(robot, posture, method, rows, tangential, factor * v)[0] <= 1.0 + 1e-9
    (below, below_edges), (above, above_edges) = (rows_at(robot, posture, method, rows, tangential, (1 + e) * v)
                                                  for e in (-1e-9, 1e-9))
    assert below <= 1.0 + 1e-9
    if np.linalg.norm(above_edges - below_edges) <= 1e-9 * np.linalg.norm(below_edges):  # the same edges
        assert rows_at(robot, posture, method, rows, tangential, v)[0] == pytest.approx(1.0, rel=1e-9)
    else:
        assert above > 1.0



def test_where_the_pyramid_binds_below_the_certain_slip_the_preview_answers_that_speed(robot):
    """``elbow_left``, crb, mu = 0.5, sliding at 0.1875 m/s along t2: the preview's rows are the
    sector's while its slip is certain and the 3-edge pyramid's above (the pyramid rows of k = 3:
    mu_3 = mu / cos(pi / 3) = 2 mu); those bind at a lower speed than the highest speed of a certain
    slip, so the answer is that speed: just slower the rows are the sector's and hold with none at
    its limit, just faster they are the pyramid's and fail."""
    posture = PANDA.postures["elbow_left"]
    normal, terms, setting = posture.surface.normal, robot.terms(posture.q), Setting("crb", 0.2)
    tangential, preview, pyramid = tangential_of(normal, 0.0, 0.1875), FrictionRows(0.5, 3, "slip"), FrictionRows(0.5, 3)
    answer = frictional_max_speed(robot, terms, normal, tangential, setting, preview)
    v = answer.max_speed.speed
    assert answer.max_speed.criterion == "certain_slip"
    assert frictional_max_speed(robot, terms, normal, tangential, setting, pyramid).max_speed.speed < v
    (below, below_edges), (above, above_edges) = (rows_at(robot, posture, "crb", preview, tangential, (1 + e) * v)
                                                  for e in (-1e-9, 1e-9))
    pyramid_edges = rows_at(robot, posture, "crb", pyramid, tangential, v)[1]
    np.testing.assert_allclose(above_edges, pyramid_edges, rtol=1e-12, atol=1e-12 * np.max(np.abs(pyramid_edges)))
    assert not np.allclose(below_edges, pyramid_edges)
    assert below < 0.5 and above > 1.0

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


HELD_METHODS = ["crb", "gm", "classical"]
STANCE_NAMES = sorted(STANCES)


@settings(max_examples=12, deadline=None)
@given(standing_states(), st.sampled_from(HELD_METHODS), st.sampled_from([0.0, 0.4]), st.floats(-0.2, 0.2))
def test_on_held_contacts_zero_friction_is_the_frictionless_closed_form(state, method, restitution, slide):
    """Random standing postures: mu = 0 gives the frictionless closed form (every criterion's
    bound) to 1e-12; for crb and gm, whose frictionless impulse is along n, a vanishing mu too,
    and a slide along the wall changes their feet and capture bounds by nothing (their impulse
    does not see it)."""
    _, q, _ = state
    g1, setting = g1_robot(), Setting(method, restitution)
    terms = g1.terms(q)
    frictionless = closed_form_max_speed(g1, terms, NORMAL, setting)
    zero = frictional_max_speed(g1, terms, NORMAL, np.zeros(3), setting, FrictionRows(0.0))
    assert (zero.max_speed.criterion, zero.max_speed.where) == (frictionless.criterion, frictionless.where)
    for criterion, bound in frictionless.bounds.items():
        assert zero.max_speed.bounds[criterion].speed == pytest.approx(bound.speed, rel=1e-12, abs=0.0)
    if method == "classical":
        return
    vanishing = frictional_max_speed(g1, terms, NORMAL, np.zeros(3), setting, FrictionRows(1e-13))
    assert vanishing.max_speed.speed == pytest.approx(frictionless.speed, rel=1e-10)
    sliding = frictional_max_speed(g1, terms, NORMAL, np.array([0.0, slide, 0.0]), setting, FrictionRows(0.0))
    for criterion in ("foot_slip", "foot_lift", "capture"):
        assert sliding.max_speed.bounds[criterion].speed == pytest.approx(frictionless.bounds[criterion].speed, rel=1e-9)


def vertex_margins(q, method, speed, mu, edges, slide, heights):
    """Each criterion's smallest margin over the vertices of the cone's section at the normal speed
    ``speed`` sliding at (0, slide, 0), from first principles (``criterion_margins``): the
    predictor's own impulse and each edge's, the impulse along d_i = n + mu_k t_i that ends
    compression (``vertex_impulses``), with the predictor's held-contact W and jump map."""
    g1 = g1_robot()
    terms = g1.terms(q)
    model = JUMP_MODELS[method]
    arm = g1.base_nv + np.array([g1.joint_index(j) for j in g1.description.contact.joints])
    dq_pre = np.zeros(g1.nv)
    dq_pre[arm] = np.linalg.pinv(terms.J[:, arm]) @ np.array([speed, slide, 0.0])  # -speed n + slide e_y
    v_minus = terms.J @ dq_pre
    W = held_response_maps(model, terms, NORMAL, 0.0)[1]
    impulses = [model.predict(terms, NORMAL, v_minus).impulse, *vertex_impulses(W, v_minus, pyramid_directions(NORMAL, mu, edges))]
    margins = {}
    for impulse in impulses:
        jump = model.predict(terms, NORMAL, None, impulse=impulse)
        for criterion, margin in criterion_margins(q, dq_pre, jump, heights, HAND_IMPACT_DURATION).items():
            margins[criterion] = min(margins.get(criterion, np.inf), margin)
    return margins


@settings(max_examples=10, deadline=None)
@given(st.sampled_from(STANCE_NAMES), st.sampled_from(HELD_METHODS), st.floats(0.05, 1.0), st.integers(3, 8),
       st.sampled_from([0.0, 0.1]))
def test_on_held_contacts_every_vertex_meets_every_criterion_at_the_answer_and_the_binding_one_is_tight(
    name, method, mu, edges, slide
):
    """At the frictional closed form's speed every vertex's joint velocities, feet (cone and sole)
    and capture point hold, the binding criterion is tight on one vertex, and 1 % faster it fails;
    friction never raises the frictionless closed form (at the same slide)."""
    g1, stance = g1_robot(), STANCES[name]
    q = stance_posture(g1, stance)
    heights = np.repeat([stance.height(k) for k in range(len(stance.feet))], 4)
    terms = g1.terms(q)
    tangential = np.array([0.0, slide, 0.0])
    answer = frictional_max_speed(g1, terms, NORMAL, tangential, Setting(method), FrictionRows(mu, edges))
    without = frictional_max_speed(g1, terms, NORMAL, tangential, Setting(method), FrictionRows(0.0))
    v = answer.max_speed.speed
    assert 0.0 < v <= without.max_speed.speed * (1 + 1e-12)
    at = vertex_margins(q, method, v, mu, edges, slide, heights)
    assert min(at.values()) >= -1e-6
    assert at[answer.max_speed.criterion] == pytest.approx(0.0, abs=1e-6)
    assert vertex_margins(q, method, 1.01 * v, mu, edges, slide, heights)[answer.max_speed.criterion] < 0.0
    assert answer.block in ("frictionless", *(f"edge {i}" for i in range(edges)))
    assert answer.mode in ("slip", "stick", "reversal")
