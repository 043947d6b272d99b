import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.inverse_kinematics import (
    AXIS_TOLERANCE,
    POSITION_TOLERANCE,
    UnreachableStartError,
    approach_start,
    contact_posture,
    contact_postures,
)
from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError

from conftest import JOINTS, joint_positions
from reference.inverse_kinematics import reference_contact_postures


@settings(max_examples=15, deadline=None)
@given(q=joint_positions(margin=0.3), offset=st.lists(st.floats(-0.15, 0.15), min_size=JOINTS, max_size=JOINTS))
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
    solved = contact_posture(robot, [2.0, 0.0, 0.5], np.array([-1.0, 0.0, 0.0]), PANDA.postures["elbow_up"].q)
    assert not solved.reachable
    assert solved.position_error > 0.5
    assert np.all(solved.q >= robot.q_min) and np.all(solved.q <= robot.q_max)


def test_a_named_posture_is_its_own_solution(robot):
    p = PANDA.postures["elbow_left"]
    point = robot.contact_point(p.q)
    solved = contact_posture(robot, point, p.surface.normal, p.q)
    assert solved.reachable
    assert np.linalg.norm(robot.contact_point(solved.q) - point) <= POSITION_TOLERANCE


@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_batched_postures_reach_their_targets_and_follow_the_one_target_iteration(robot, seed):
    """Targets by FK of random postures (reachable) and a point out of reach, one batch from one
    seed: each batched posture (the kernel and its numpy reference, equal to 1e-9) meets its
    target to tolerance, within the limits, and equals the one-target iteration's posture up to
    rounding (same steps, same stopping rule: a last step taken by one and not the other on a
    rounding difference moves q by far less than 1e-6 rad)."""
    rng = np.random.default_rng(seed)
    start = PANDA.postures["elbow_up"].q
    Q = np.clip(start + rng.uniform(-0.4, 0.4, (6, JOINTS)), robot.q_min + 0.2, robot.q_max - 0.2)
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
        np.testing.assert_allclose(batch.q[i], single.q, atol=1e-6)
        if batch.reachable[i]:
            reached = robot.contact_frame(batch.q[i])
            assert np.linalg.norm(reached.translation - point) <= POSITION_TOLERANCE
            assert np.linalg.norm(np.cross(reached.rotation[:, 2], -normal)) <= AXIS_TOLERANCE
            assert reached.rotation[:, 2] @ -normal > 0.0


def test_start_posture_is_backed_away_along_the_normal_with_the_same_orientation(robot):
    q_contact = PANDA.postures["elbow_left"].q
    q0 = approach_start(robot, q_contact, DEFAULT_WALL, 0.03)
    contact, start = robot.contact_frame(q_contact), robot.contact_frame(q0)
    np.testing.assert_allclose(start.translation, contact.translation + 0.03 * DEFAULT_WALL.normal, atol=1e-6)
    np.testing.assert_allclose(start.rotation, contact.rotation, atol=1e-5)
    assert np.all((q0 >= robot.q_min) & (q0 <= robot.q_max))


def test_start_posture_faces_a_tilted_wall(robot):
    normal = np.array([-1.0, 0.0, 0.3]) / np.linalg.norm([-1.0, 0.0, 0.3])
    wall = Surface(point=np.array([0.6, 0.0, 0.7]), normal=normal)
    q0 = approach_start(robot, PANDA.postures["elbow_up"].q, wall, 0.02)
    start = robot.contact_frame(q0)
    assert wall.signed_distance(start.translation) == pytest.approx(0.02, abs=1e-6)
    np.testing.assert_allclose(start.rotation[:, 2], -normal, atol=1e-6)


def test_unreachable_wall_is_rejected(robot):
    far = Surface(point=np.array([1.6, 0.0, 0.0]), normal=np.array([-1.0, 0.0, 0.0]))
    with pytest.raises(UnreachableStartError, match="out of reach"):
        approach_start(robot, PANDA.postures["elbow_up"].q, far, 0.02)


@settings(max_examples=10, deadline=None)
@given(name=st.sampled_from(sorted(PANDA.postures)), distance=st.floats(0.0, 0.1))
def test_an_approach_start_is_a_contact_posture_on_the_plane_moved_back_by_the_distance(robot, name, distance):
    """The two uses of the one iteration agree: the start posture, a whole-pose target, already
    solves the tip-and-axis target of its own point and the surface normal (no step taken)."""
    posture = PANDA.postures[name]
    q0 = approach_start(robot, posture.q, posture.surface, distance)
    point = robot.contact_point(q0)
    assert posture.surface.signed_distance(point) == pytest.approx(distance, abs=1e-6)
    solved = contact_posture(robot, point, posture.surface.normal, q0)
    assert solved.reachable
    np.testing.assert_array_equal(solved.q, q0)


@pytest.mark.parametrize("distance", [-0.01, float("nan"), float("inf")])
def test_a_negative_or_non_finite_start_distance_is_bad_input(robot, distance):
    with pytest.raises(BadInputError, match="start distance"):
        approach_start(robot, PANDA.postures["elbow_up"].q, DEFAULT_WALL, distance)

