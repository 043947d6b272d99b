import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.inverse_kinematics import (
    AXIS_TOLERANCE,
    POSITION_TOLERANCE,
    contact_posture,
)
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
