"""Constraints: every row set is equivalent to the physical limit it stands for, on the arms and on the
standing G1 (the expected impact and its post-impact rows with held contacts)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.constraints import reference_recoverable, reference_rows
from whole_body_states import NORMAL, approach_velocity, stance, standing_states, upright, wall_ahead
from whole_body_states import robot as g1

from conftest import JOINTS, random_state
from impactqp.constraints import (
    AccelerationLimit,
    ControlCycle,
    ExpectedImpact,
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
)
from impactqp.constraints.impact_model import ActivationRule
from impactqp.controller.model.friction_pyramid import FrictionRows
from impactqp.controller.model.jump import held_impulse, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError

DT = 0.001
SEEDS = st.integers(0, 2**32 - 1)


def cycle(robot, previous_ddq=None):
    previous = np.zeros(JOINTS) if previous_ddq is None else previous_ddq
    return ControlCycle.after(previous, DT, robot.ddq_max, robot.dddq_max)


def inside(rows, ddq):
    value = ddq if rows.C is None else rows.C @ ddq
    return bool(np.all(value >= rows.lower - 1e-9) and np.all(value <= rows.upper + 1e-9))


def test_reachable_accelerations_respect_the_acceleration_and_jerk_limits(robot):
    previous = 0.9 * robot.ddq_max * np.array([1, -1, 1, -1, 1, -1, 1])
    c = cycle(robot, previous)
    rows = AccelerationLimit().compute(None, c)
    assert np.all(rows.lower <= previous) and np.all(previous <= rows.upper)
    assert np.all(rows.upper <= robot.ddq_max) and np.all(rows.lower >= -robot.ddq_max)
    assert np.all(rows.upper - previous <= robot.dddq_max * DT + 1e-12)
    assert np.all(previous - rows.lower <= robot.dddq_max * DT + 1e-12)


@settings(max_examples=30, deadline=None)
@given(SEEDS)
def test_velocity_box_is_the_commanded_velocity_limit(robot, seed):
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng, speed=0.99)
    rows = VelocityLimit(robot.dq_max).compute(terms, cycle(robot))
    assert np.all(rows.lower <= rows.upper)
    for ddq in rng.uniform(rows.lower, rows.upper, (5, JOINTS)):
        assert np.all(np.abs(terms.dq + ddq * DT) <= robot.dq_max + 1e-12)


def test_velocity_box_brakes_within_the_acceleration_limits_from_an_overspeed(robot):
    terms = robot.terms(PANDA.postures["elbow_up"].q, 1.2 * robot.dq_max)
    c = cycle(robot)
    rows = VelocityLimit(robot.dq_max).compute(terms, c)
    assert np.allclose(rows.upper, c.acceleration_lower)  # brake as hard as allowed


@pytest.mark.parametrize("joint", [0, 3, 6])
def test_position_limit_stops_every_joint_before_its_limit(robot, joint):
    """Push a joint at full speed towards its upper limit, always taking the largest
    acceleration the position, velocity and acceleration limits allow: it stops inside the
    limit and the bounds never cross."""
    constraint = PositionLimit(robot.q_min, robot.q_max, robot.ddq_max)
    acceleration, velocity = AccelerationLimit(), VelocityLimit(robot.dq_max)
    q = 0.5 * (robot.q_min + robot.q_max)
    q[joint] = robot.q_max[joint] - 0.5  # inside the braking horizon at full speed
    dq = np.zeros(JOINTS)
    dq[joint] = robot.dq_max[joint]
    ddq = np.zeros(JOINTS)
    for _ in range(1500):
        terms = robot.terms(q, dq)
        c = cycle(robot, ddq)
        boxes = [k.compute(terms, c) for k in (constraint, acceleration, velocity)]
        lower = np.max([b.lower for b in boxes], axis=0)
        upper = np.min([b.upper for b in boxes], axis=0)
        assert np.all(lower <= upper + 1e-12)
        ddq = upper.copy()
        dq_next = dq + ddq * DT
        q = q + 0.5 * DT * (dq + dq_next)
        dq = dq_next
        assert q[joint] <= robot.q_max[joint] + 1e-9
    assert abs(dq[joint]) < 1e-3


@settings(max_examples=30, deadline=None)
@given(SEEDS)
def test_torque_rows_are_the_inverse_dynamics_limits(robot, seed):
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng)
    rows = TorqueLimit(robot.tau_max).compute(terms, cycle(robot))
    for ddq in rng.uniform(-30.0, 30.0, (20, JOINTS)):
        tau = terms.M @ ddq + terms.h
        within = np.all(np.abs(tau) <= robot.tau_max)
        assert within == inside(rows, ddq) or np.min(np.abs(np.abs(tau) - robot.tau_max)) < 1e-6


def surface_ahead(terms, gap=0.05):
    normal = np.array([-1.0, 0.0, 0.0])
    return Surface(terms.contact_point - gap * normal, normal)


@pytest.mark.parametrize("name", ["crb", "gm", "classical", "classical_normal"])
@pytest.mark.parametrize("restitution", [0.0, 0.5])
def test_impact_matrices_match_the_jump_models(robot, name, restitution):
    """A = K G J and P = J^T G J of the expected impact, from the predictor's G and K."""
    terms = robot.terms(PANDA.postures["elbow_right"].q, np.full(JOINTS, 0.1))
    surface = surface_ahead(terms)
    matrices = ExpectedImpact(surface, name, restitution).matrices(terms)
    model = jump_model(name)
    maps = model.maps(terms, surface.normal, restitution)
    assert np.allclose(matrices.jump_matrix, maps.K @ maps.G @ terms.J, atol=1e-10)
    dq = np.linspace(-0.5, 0.5, JOINTS)
    impulse = model.predict(terms, surface.normal, terms.J @ dq, restitution).impulse
    assert np.allclose(matrices.torque_matrix @ dq, terms.J.T @ impulse, atol=1e-10)


@settings(max_examples=25, deadline=None)
@given(SEEDS, st.sampled_from(["crb", "gm", "classical"]))
def test_impact_rows_are_the_post_impact_velocity_and_impulsive_torque_limits(robot, seed, name):
    """The rows bound the post-impact velocity and impulsive torque at dq + ddq h (h the jerk
    horizon of the cycle). The cycle's reachable accelerations are made wide enough that no
    row needs the recovery relaxation (tested below)."""
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng, speed=0.2)
    surface = surface_ahead(terms)
    impact = ExpectedImpact(surface, name, restitution=0.3, rule=ActivationRule(always_active=True))
    c = ControlCycle.after(np.zeros(JOINTS), DT, 1e6 * robot.ddq_max, 1e9 * robot.dddq_max)
    c = ControlCycle(DT, c.acceleration_lower, c.acceleration_upper, cycle(robot).horizon)
    velocity_rows = PostImpactVelocityLimit(impact, robot.dq_max).compute(terms, c)
    torque_rows = ImpulsiveTorqueLimit(impact, robot.tau_max, robot.dq_max, 0.015).compute(terms, c)
    model = jump_model(name)
    assert c.horizon == pytest.approx(max(DT, np.max(robot.ddq_max / robot.dddq_max)))
    for ddq in rng.uniform(-200.0, 200.0, (20, JOINTS)):
        pre = terms.dq + ddq * c.horizon
        prediction = model.predict(terms, surface.normal, terms.J @ pre, 0.3)
        post_ratio = np.max(np.abs(pre + prediction.dq_jump) / robot.dq_max)
        torque_ratio = np.max(np.abs(terms.J.T @ prediction.impulse) / 0.015 / robot.tau_max)
        if abs(post_ratio - 1.0) > 1e-9:
            assert inside(velocity_rows, ddq) == (post_ratio < 1.0)
        if abs(torque_ratio - 1.0) > 1e-9:
            assert inside(torque_rows, ddq) == (torque_ratio < 1.0)


def test_violated_impact_rows_ask_for_the_largest_reachable_correction(robot):
    """Approaching far faster than the impact allows: each row is relaxed to the extreme that
    the cycle's reachable accelerations allow, so it stays feasible on its own; rows that can
    be met are left as they are."""
    q = PANDA.postures["elbow_up"].q
    terms = robot.terms(q, 0.8 * approach_direction(robot, robot.terms(q), np.array([-1.0, 0.0, 0.0])))
    impact = ExpectedImpact(surface_ahead(terms), "crb", rule=ActivationRule(always_active=True))
    c = cycle(robot)
    rows = ImpulsiveTorqueLimit(impact, robot.tau_max, robot.dq_max, 0.015).compute(terms, c)
    low, high = rows.C * c.acceleration_lower, rows.C * c.acceleration_upper
    reach_min, reach_max = np.minimum(low, high).sum(axis=1), np.maximum(low, high).sum(axis=1)
    assert np.all(rows.lower <= reach_max + 1e-9) and np.all(rows.upper >= reach_min - 1e-9)
    pre = impact.matrices(terms).torque_matrix @ terms.dq
    violated = np.abs(pre) > robot.tau_max * 0.015
    assert violated.any()
    relaxed = np.isclose(rows.upper, reach_min, rtol=1e-12, atol=1e-9)
    assert np.any(relaxed | np.isclose(rows.lower, reach_max, rtol=1e-12, atol=1e-9))
    unchanged = ~violated
    scale = robot.dq_max / (robot.tau_max * 0.015) / c.horizon
    np.testing.assert_allclose(rows.upper[unchanged], ((robot.tau_max * 0.015 - pre) * scale)[unchanged])


def test_activation_rule(robot):
    q = PANDA.postures["elbow_up"].q
    at_rest = robot.terms(q)
    normal = np.array([-1.0, 0.0, 0.0])
    tip = at_rest.contact_point
    near = Surface(tip - 0.05 * normal, normal)
    far = Surface(tip - 0.5 * normal, normal)
    assert ExpectedImpact(near).is_active(at_rest)
    assert not ExpectedImpact(far).is_active(at_rest)
    assert ExpectedImpact(far, rule=ActivationRule(always_active=True)).is_active(at_rest)
    direction = np.linalg.pinv(at_rest.J6) @ np.concatenate([-normal, np.zeros(3)])
    approaching_fast = robot.terms(q, 2.0 * direction)  # 2 m/s: 0.5 m in 0.25 s
    assert ExpectedImpact(far, rule=ActivationRule(lookahead_time=0.3)).is_active(approaching_fast)
    receding = robot.terms(q, -0.1 * direction)
    assert not ExpectedImpact(near).is_active(receding)
    rows = PostImpactVelocityLimit(ExpectedImpact(far), robot.dq_max).compute(at_rest, cycle(robot))
    assert np.all(np.isinf(rows.lower)) and np.all(np.isinf(rows.upper))


@settings(max_examples=50, deadline=None)
@given(previous=st.lists(st.floats(-1.0, 1.0), min_size=JOINTS, max_size=JOINTS))
def test_advancing_the_cycle_in_place_equals_a_new_cycle(robot, previous):
    """ControlCycle.advance (the controller's in-place update) gives the interval of after()."""
    previous = np.array(previous) * robot.ddq_max
    expected = ControlCycle.after(previous, DT, robot.ddq_max, robot.dddq_max)
    c = ControlCycle.after(np.zeros(JOINTS), DT, robot.ddq_max, robot.dddq_max)
    c.advance(previous, robot.ddq_max, robot.dddq_max * DT)
    np.testing.assert_array_equal(c.acceleration_lower, expected.acceleration_lower)
    np.testing.assert_array_equal(c.acceleration_upper, expected.acceleration_upper)


def _rows_of(constraint, terms, c, reference):
    n = terms.dq.shape[0]  # one column per velocity; a box bounds each
    size = n if constraint.is_box else constraint.rows
    C = None if constraint.is_box else np.full((constraint.rows, n), np.nan)
    lower, upper = np.full(size, np.nan), np.full(size, np.nan)
    if reference:
        reference_rows(constraint, terms, c, C, lower, upper)
    else:
        constraint.compute_into(terms, c, C, lower, upper)
    return C, lower, upper


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, jump=st.sampled_from(["crb", "gm", "classical"]), always=st.booleans(),
       restitution=st.floats(0.0, 1.0), friction=st.sampled_from([FrictionRows(), FrictionRows(0.4, 5), FrictionRows(0.4, 4, "slip")]))
def test_compiled_rows_equal_the_numpy_reference(robot, seed, jump, always, restitution, friction):
    """Every constraint's compiled kernel (compute_into) writes the rows its plain-numpy
    statement (tests/reference/constraints.py) gives, active or not, with and without the
    friction rows' blocks; so does the relaxation kernel."""
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng)
    c = cycle(robot, rng.uniform(-0.5, 0.5, JOINTS) * robot.ddq_max)
    surface = Surface(terms.contact_point - rng.uniform(0.0, 0.2) * np.array([-1.0, 0.0, 0.0]), [-1.0, 0.0, 0.0])
    impact = ExpectedImpact(surface, jump, restitution, ActivationRule(always_active=always), friction=friction)
    constraints = [
        AccelerationLimit(), PositionLimit(robot.q_min, robot.q_max, robot.ddq_max, 0.5, 0.01),
        VelocityLimit(robot.dq_max), TorqueLimit(robot.tau_max), PostImpactVelocityLimit(impact, robot.dq_max),
        ImpulsiveTorqueLimit(impact, robot.tau_max, robot.dq_max, 0.015),
    ]
    for constraint in constraints:
        fast, reference = _rows_of(constraint, terms, c, False), _rows_of(constraint, terms, c, True)
        for a, b in zip(fast, reference):
            if a is not None:
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9, err_msg=constraint.name)
        if constraint.relaxed:
            C, lower, upper = fast
            lower_ref, upper_ref = lower.copy(), upper.copy()
            c.recoverable(C, lower, upper)
            reference_recoverable(c, C, lower_ref, upper_ref)
            np.testing.assert_allclose(lower, lower_ref, rtol=1e-12, atol=1e-9)
            np.testing.assert_allclose(upper, upper_ref, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("name", ["crb", "gm", "classical", "classical_normal"])
def test_arm_impact_matrices_are_those_of_each_fill_written_into_the_arrays_of_the_first(robot, name):
    """At every new fill of the terms the expected impact's A, P and G are the model's of that
    state; the crb, gm and classical models write them into the arrays of the first fill (no
    allocation per cycle), classical_normal returns new ones."""
    rng = np.random.default_rng(7)
    impact = ExpectedImpact(surface_ahead(robot.terms(PANDA.postures["elbow_right"].q)), name, 0.2)
    terms = robot.empty_terms()
    first = None
    for _ in range(3):
        state = random_state(robot, rng)
        robot.update_terms(terms, state.q, state.dq)
        matrices = impact.matrices(terms)
        expected = jump_model(name).unit_matrices(terms, impact.surface.normal, 0.2)
        for got, reference in zip(matrices[:3], expected[:3]):
            np.testing.assert_allclose(got, reference, rtol=0.0, atol=1e-12 * np.abs(reference).max())
        if first is None:
            first = matrices.jump_matrix
        else:
            assert (matrices.jump_matrix is first) == (name != "classical_normal")



def kept_arrays_are_read_only_or_unchanged(kept, before) -> None:
    """What a caller kept of ``matrices`` past the next fill: each array read-only, or as it was."""
    for array, value in zip(kept, before):
        if array.flags.writeable:
            np.testing.assert_array_equal(array, value)
        else:
            with pytest.raises(ValueError, match="read-only"):
                array[0, 0] = 1.0


@pytest.mark.parametrize("name", ["crb", "gm", "classical", "classical_normal"])
def test_arm_impact_matrices_kept_past_the_next_fill_cannot_be_written_or_stay_as_they_were(robot, name):
    """``matrices`` is valid until the next fill of the terms: a kept A, P or G is either a
    read-only view of the buffers that fill overwrites, or an array it leaves alone."""
    rng = np.random.default_rng(11)
    impact = ExpectedImpact(surface_ahead(robot.terms(PANDA.postures["elbow_right"].q)), name, 0.2)
    terms = robot.empty_terms()
    state = random_state(robot, rng)
    robot.update_terms(terms, state.q, state.dq)
    kept = impact.matrices(terms)[:3]
    before = [array.copy() for array in kept]
    state = random_state(robot, rng)
    robot.update_terms(terms, state.q, state.dq)
    assert not np.allclose(impact.matrices(terms).jump_matrix, before[0])  # a fill of another state
    kept_arrays_are_read_only_or_unchanged(kept, before)
    for rows, view in zip(impact.row_matrices(terms)[:3], impact.matrices(terms)[:3]):  # the arrays the rows read
        np.testing.assert_array_equal(rows, view)


@pytest.mark.parametrize("method", ["crb", "gm", "classical"])
def test_g1_impact_matrices_kept_past_the_next_fill_cannot_be_written_or_stay_as_they_were(method):
    q = stance("wide")
    impact = ExpectedImpact(wall_ahead(q), method, restitution=0.3, held_contacts=True)
    kept = impact.matrices(g1().terms(q, approach_velocity(q, 0.2)))
    before = [array.copy() for array in kept]
    impact.matrices(g1().terms(stance("parallel"), approach_velocity(q, 0.3)))
    kept_arrays_are_read_only_or_unchanged(kept, before)


@pytest.mark.parametrize("name, mode", [("crb", "pyramid"), ("gm", "slip"), ("classical", "pyramid")])
def test_arm_edge_matrices_kept_past_the_next_fill_cannot_be_written(robot, name, mode):
    """``edge_matrices`` is valid until the next fill, as ``matrices``: a kept A_i or P_i is a
    read-only view of the buffer that fill overwrites; the rows read the buffer itself."""
    rng = np.random.default_rng(13)
    impact = ExpectedImpact(surface_ahead(robot.terms(PANDA.postures["elbow_right"].q)), name, 0.2,
                            friction=FrictionRows(0.4, 4, mode))
    terms = robot.empty_terms()
    state = random_state(robot, rng)
    robot.update_terms(terms, state.q, state.dq)
    kept = impact.edge_matrices(terms)
    before = [array.copy() for array in kept]
    state = random_state(robot, rng)
    robot.update_terms(terms, state.q, state.dq)
    assert not np.allclose(impact.edge_matrices(terms).jump, before[0])  # a fill of another state
    for array in kept:
        with pytest.raises(ValueError, match="read-only"):
            array[0, 0, 0] = 1.0
    for rows, view in zip(impact.edge_row_matrices(terms), impact.edge_matrices(terms)):
        assert rows.flags.writeable
        np.testing.assert_array_equal(rows, view)


@pytest.mark.parametrize("method", ["crb", "gm", "classical"])
def test_g1_edge_matrices_kept_past_the_next_fill_cannot_be_written(method):
    q = stance("wide")
    impact = ExpectedImpact(wall_ahead(q), method, restitution=0.3, held_contacts=True, friction=FrictionRows(0.3, 4))
    kept = impact.edge_matrices(g1().terms(q, approach_velocity(q, 0.2)))
    impact.edge_matrices(g1().terms(stance("parallel"), approach_velocity(q, 0.3)))
    for array in kept:
        with pytest.raises(ValueError, match="read-only"):
            array[0, 0, 0] = 1.0


@pytest.mark.parametrize("method, mode", [("crb", "pyramid"), ("gm", "slip"), ("classical", "pyramid")])
def test_g1_edge_impulse_maps_kept_past_the_next_fill_cannot_be_written(method, mode):
    """``edge_impulse_maps`` is valid until the next fill, as ``edge_matrices``: a kept G_i is a
    read-only view of the buffer that fill overwrites (it shows the new state's maps); the rows
    read the buffer itself, writable."""
    q = stance("wide")
    impact = ExpectedImpact(wall_ahead(q), method, restitution=0.3, held_contacts=True, friction=FrictionRows(0.3, 4, mode))
    kept = impact.edge_impulse_maps(g1().terms(q, approach_velocity(q, 0.2)))
    before = kept.copy()
    with pytest.raises(ValueError, match="read-only"):
        kept[0, 0, 0] = 1.0
    impact.edge_impulse_maps(g1().terms(stance("parallel"), approach_velocity(stance("parallel"), 0.3)))
    assert not np.array_equal(kept, before)  # the buffer holds the new fill's maps
    with pytest.raises(ValueError, match="read-only"):
        kept[0, 0, 0] = 1.0
    rows = impact.edge_row_impulse_maps(g1().terms(stance("parallel"), approach_velocity(stance("parallel"), 0.3)))
    assert rows.flags.writeable
    np.testing.assert_array_equal(rows, kept)


@pytest.mark.parametrize(
    "keyword, value, fragment",
    [
        ("restitution", 1.5, "the restitution must lie in [0, 1]"),
        ("restitution", float("nan"), "the restitution must lie in [0, 1]"),
        ("restitution", "0.3", "the restitution must be a number in [0, 1]"),
        ("lookahead_distance", -0.1, "the look-ahead distance"),
        ("lookahead_time", float("inf"), "the look-ahead time"),
        ("release_speed", 1e9, "the release speed"),
        ("always_active", "yes", "always_active"),
    ],
)
def test_impact_model_checks_its_inputs_with_the_validation_module(keyword, value, fragment):
    with pytest.raises(BadInputError) as caught:
        if keyword == "restitution":
            ExpectedImpact(PANDA.postures["elbow_up"].surface, "crb", **{keyword: value})
        else:
            ExpectedImpact(PANDA.postures["elbow_up"].surface, "crb", ActivationRule(**{keyword: value}))
    assert fragment in str(caught.value)


def test_joint_limit_boxes_on_a_floating_base_bound_the_trailing_joints_only():
    """Position and velocity limits with one limit per joint and the base's velocities besides:
    the base's entries are unbounded, the joints' equal the same limits applied to the joints
    alone."""
    from whole_body_states import approach_velocity, robot, stance

    model = robot()
    q = stance("staggered")
    v = approach_velocity(q, 0.5)
    terms = model.terms(q, v)
    wide = ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), 0.0025)
    narrow = ControlCycle(0.001, np.full(model.n_joints, -1e9), np.full(model.n_joints, 1e9), 0.0025)
    base = model.base_nv

    class Joints:  # the joints' part of the state, as the arm's terms
        q, dq = terms.q[model.base_nq:], terms.dq[base:]

    for box in (PositionLimit(model.q_min, model.q_max, model.ddq_max), VelocityLimit(model.dq_max)):
        full, joints = box.compute(terms, wide), box.compute(Joints, narrow)
        assert np.all(full.lower[:base] == -1e9) and np.all(full.upper[:base] == 1e9)
        np.testing.assert_array_equal(full.lower[base:], joints.lower)
        np.testing.assert_array_equal(full.upper[base:], joints.upper)


H = 0.0025  # s: a jerk horizon of the G1's cycle


def test_g1_rule_is_on_while_approaching_near_the_wall_and_off_when_leaving_or_far():
    q = stance("parallel")
    impact = ExpectedImpact(wall_ahead(q, 0.05), held_contacts=True)
    far = ExpectedImpact(wall_ahead(q, 0.5), held_contacts=True)
    approaching, leaving = approach_velocity(q, 0.3), approach_velocity(q, -0.3)
    assert impact.is_active(g1().terms(q, approaching))
    assert not impact.is_active(g1().terms(q, leaving))
    assert not far.is_active(g1().terms(q, approaching))
    assert ExpectedImpact(wall_ahead(q, 0.5), rule=ActivationRule(always_active=True), held_contacts=True).is_active(g1().terms(q, leaving))


@pytest.mark.parametrize("method", ["crb", "gm", "classical"])
def test_g1_maps_are_the_held_contact_predictors_of_the_state_computed_once_per_state(method):
    q = stance("wide")
    impact = ExpectedImpact(wall_ahead(q), method, restitution=0.3, held_contacts=True)
    terms = g1().terms(q, approach_velocity(q, 0.2))
    maps = impact.matrices(terms)
    assert impact.matrices(terms) is maps
    np.testing.assert_allclose(maps.jump_matrix, jump_model(method).unit_matrices(terms, NORMAL, 0.3).jump_matrix)
    other = g1().terms(stance("parallel"), approach_velocity(q, 0.3))
    for new, own in zip(impact.matrices(other), jump_model(method).unit_matrices(other, NORMAL, 0.3)):
        np.testing.assert_allclose(new, own)


@settings(max_examples=10, deadline=None)
@given(standing_states(max_speed=1.0), st.sampled_from(HELD_CONTACT_METHODS), st.integers(0, 2**31))
def test_g1_held_impulse_map_keeps_the_feet_still_under_any_impulse(state, method, seed):
    """With lambda = -Z iota the held contacts' impulsive wrenches, the velocity change
    M^-1 (J^T iota + Jf^T lambda) leaves the feet still (Jf dv = 0) for any impulse iota, and
    lambda is ``jump.held_impulse``'s (M from crba, not the kernel's M^-1)."""
    _, q, v = state
    terms = g1().terms(q, v)
    impact = ExpectedImpact(wall_ahead(q), method, held_contacts=True)
    Z, Jf = impact.held_impulse_map(terms), terms.held_jacobian
    assert Z.shape == (Jf.shape[0], 3)
    impulse = np.random.default_rng(seed).normal(size=3)
    wrenches = -Z @ impulse
    dv = np.linalg.solve(terms.M, terms.J.T @ impulse + Jf.T @ wrenches)
    np.testing.assert_allclose(Jf @ dv, 0.0, atol=1e-9 * (1.0 + np.abs(dv).max()))
    np.testing.assert_allclose(wrenches, held_impulse(terms, impulse), rtol=1e-8, atol=1e-9 * (1.0 + np.abs(wrenches).max()))


@pytest.mark.parametrize("name", ["robust", "classical_normal", "unknown"])
def test_only_the_held_contact_models_are_accepted_with_held_contacts(name):
    with pytest.raises(BadInputError):
        ExpectedImpact(wall_ahead(stance("parallel")), name, held_contacts=True)


@settings(max_examples=15, deadline=None)
@given(standing_states(), st.sampled_from(HELD_CONTACT_METHODS), st.floats(0.05, 3.0), st.integers(0, 2**31))
def test_g1_rows_hold_exactly_when_the_predicted_post_impact_joint_velocities_are_in_the_limits(
    state, method, speed, seed
):
    """C dv <= u and >= l  <=>  |S (v' + dv_jump(v'))| <= dq_max with v' = v + dv h, dv_jump
    the feet-held predictor's jump at v- = J v' and S the joints' rows."""
    name, q, v = state
    model = g1()
    v = v + approach_velocity(q, speed)
    terms = model.terms(q, v)
    impact = ExpectedImpact(wall_ahead(q), method, rule=ActivationRule(always_active=True), held_contacts=True)
    rows = PostImpactVelocityLimit(impact, model.dq_max).compute(
        terms, ControlCycle(0.001, np.full(model.nv, -1e9), np.full(model.nv, 1e9), H)
    )
    dv = np.random.default_rng(seed).normal(scale=2000.0, size=model.nv)
    v_next = v + dv * H
    post = (v_next + predict(model.terms(q), method, NORMAL, terms.J @ v_next).dq_jump)[model.base_nv:]
    inside_rows = np.all(rows.C @ dv <= rows.upper + 1e-9) and np.all(rows.C @ dv >= rows.lower - 1e-9)
    margin = np.min(model.dq_max - np.abs(post))
    if abs(margin) > 1e-6:
        assert inside_rows == (margin > 0)
    np.testing.assert_allclose(rows.C @ dv - rows.upper, (post - model.dq_max) / H, atol=1e-6 / H)


def test_g1_rows_are_unbounded_while_no_impact_is_coming():
    model = g1()
    q = model.terms(upright()).q
    limit = PostImpactVelocityLimit(ExpectedImpact(wall_ahead(q, 0.8), held_contacts=True), model.dq_max)
    rows = limit.compute(model.terms(q), ControlCycle(0.001, np.full(model.nv, -1.0), np.full(model.nv, 1.0), H))
    assert np.all(rows.lower == -np.inf) and np.all(rows.upper == np.inf)


@settings(max_examples=10, deadline=None)
@given(standing_states(max_speed=1.0), st.sampled_from(HELD_CONTACT_METHODS), st.booleans())
def test_g1_compiled_post_impact_rows_equal_the_numpy_reference(state, method, always):
    """On a floating base the kernel writes the joints' rows S (I + A) of the numpy statement."""
    _, q, v = state
    model = g1()
    terms = model.terms(q, v + approach_velocity(q, 0.3))
    c = ControlCycle(0.001, np.full(model.nv, -1.0), np.full(model.nv, 1.0), H)
    impact = ExpectedImpact(wall_ahead(q), method, rule=ActivationRule(always_active=always), held_contacts=True)
    limit = PostImpactVelocityLimit(impact, model.dq_max)
    for a, b in zip(_rows_of(limit, terms, c, False), _rows_of(limit, terms, c, True)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9)
