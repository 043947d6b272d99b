import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.inverse_kinematics import (
    AXIS_TOLERANCE,
    POSITION_TOLERANCE,
    contact_posture,
    contact_postures,
    reference_contact_postures,
)
from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.postures import POSTURES

from conftest import joint_positions


@settings(max_examples=15, deadline=None)
@given(q=joint_positions(margin=0.3), offset=st.lists(st.floats(-0.15, 0.15), min_size=7, max_size=7))
def test_a_posture_near_the_seed_is_found_and_its_forward_kinematics_meets_the_target(robot, q, offset):
    """Target built by FK of q; seed q + offset: the solution puts the tip on the point, z on -n."""
    frame = robot.contact_frame(q)
    point, normal = frame.translation, -frame.rotation[:, 2]
    solved = contact_posture(robot, point, normal, q + np.array(offset))
    assert solved.reachable
    reached = robot.contact_frame(solved.q)
    assert np.linalg.norm(reached.translation - point) <= POSITION_TOLERANCE
    assert np.linalg.norm(np.cross(reached.rotation[:, 2], -normal)) <= AXIS_TOLERANCE
    assert reached.rotation[:, 2] @ -normal > 0.0
    assert np.all(solved.q >= robot.q_min) and np.all(solved.q <= robot.q_max)


def test_a_point_out_of_reach_is_reported_unreachable_within_the_limits(robot):
    solved = contact_posture(robot, [2.0, 0.0, 0.5], np.array([-1.0, 0.0, 0.0]), POSTURES["elbow_up"].q)
    assert not solved.reachable
    assert solved.position_error > 0.5
    assert np.all(solved.q >= robot.q_min) and np.all(solved.q <= robot.q_max)


def test_a_named_posture_is_its_own_solution(robot):
    p = POSTURES["elbow_left"]
    point = robot.contact_point(p.q)
    solved = contact_posture(robot, point, p.surface.normal, p.q)
    assert solved.reachable
    assert np.linalg.norm(robot.contact_point(solved.q) - point) <= POSITION_TOLERANCE


@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_batched_postures_reach_their_targets_and_follow_the_one_target_iteration(robot, seed):
    """Targets by FK of random postures (reachable) and a point out of reach, one batch from one
    seed: each batched posture (the kernel and its numpy reference) meets its target to
    tolerance, within the limits, and equals the one-target iteration's posture up to rounding
    (same steps, same stopping rule)."""
    rng = np.random.default_rng(seed)
    start = POSTURES["elbow_up"].q
    Q = np.clip(start + rng.uniform(-0.4, 0.4, (6, 7)), robot.q_min + 0.2, robot.q_max - 0.2)
    frames = [robot.contact_frame(q) for q in Q]
    seed_frame = robot.contact_frame(start)  # last but one: the tool axis starts pointing away
    points = np.array([f.translation for f in frames] + [seed_frame.translation, [2.0, 0.0, 0.5]])
    normals = np.array([-f.rotation[:, 2] for f in frames] + [seed_frame.rotation[:, 2], [-1.0, 0.0, 0.0]])
    kinematics = BatchKinematics(robot)
    batch = contact_postures(kinematics, points, normals, start)
    reference = reference_contact_postures(kinematics, points, normals, start)
    assert np.array_equal(batch.reachable, reference.reachable)
    np.testing.assert_allclose(batch.q, reference.q, atol=1e-9)
    np.testing.assert_allclose(batch.position_error, reference.position_error, atol=1e-9)
    np.testing.assert_allclose(batch.axis_error, reference.axis_error, atol=1e-9)
    assert not batch.reachable[-1] and batch.position_error[-1] > 0.5
    assert np.all(batch.q >= robot.q_min) and np.all(batch.q <= robot.q_max)
    for i, (point, normal) in enumerate(zip(points, normals)):
        single = contact_posture(robot, point, normal, start)
        assert batch.reachable[i] == single.reachable
        np.testing.assert_allclose(batch.q[i], single.q, atol=1e-9)
        if batch.reachable[i]:
            reached = robot.contact_frame(batch.q[i])
            assert np.linalg.norm(reached.translation - point) <= POSITION_TOLERANCE
            assert np.linalg.norm(np.cross(reached.rotation[:, 2], -normal)) <= AXIS_TOLERANCE
            assert reached.rotation[:, 2] @ -normal > 0.0
