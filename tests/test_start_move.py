"""The move to the start posture: a jerk-limited straight joint path inside the scaled limits,
ending at rest on the target; a path through the surface or a target outside the joint limits
is refused before anything moves."""

import numpy as np
import pytest
from hypothesis import assume, given, settings

from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.runtime.interface import RobotState
from impactqp.controller.runtime.start_move import START_MOVE_SCALE, StartMove
from impactqp.controller.model.inverse_kinematics import approach_start
from conftest import JOINTS, joint_positions

pytest.importorskip("ruckig", reason="ruckig is not installed: pip install -e '.[franka]'")

MODEL = PandaModel()
DT = 1e-3


def at_rest(q):
    return RobotState(0.0, np.asarray(q, float), np.zeros(JOINTS), np.zeros(JOINTS))


@settings(max_examples=10, deadline=None)
@given(joint_positions(0.2), joint_positions(0.2))
def test_the_commands_follow_a_straight_path_inside_the_limits_to_rest_at_the_target(q0, target):
    assume(np.max(np.abs(target - q0)) > 1e-3)
    move = StartMove(target, MODEL, DT, at_rest(q0))
    cycles = int(np.ceil(move.duration / DT)) + 1
    dq = np.array([move.step(None).dq_cmd for _ in range(cycles)])
    assert np.allclose(dq[-1], 0.0, atol=1e-12)
    assert np.all(np.abs(dq) <= START_MOVE_SCALE * MODEL.dq_max * (1 + 1e-9))
    ddq = np.diff(np.vstack([np.zeros(JOINTS), dq]), axis=0) / DT
    assert np.all(np.abs(ddq) <= START_MOVE_SCALE * MODEL.ddq_max * (1 + 1e-6))
    jerk = np.diff(np.vstack([np.zeros((2, JOINTS)), dq]), n=2, axis=0) / DT**2
    assert np.all(np.abs(jerk) <= START_MOVE_SCALE * MODEL.dddq_max * (1 + 1e-6))
    travelled = dq.sum(axis=0) * DT  # the commanded positions, integrated over the periods
    step = target - q0
    assert np.allclose(travelled, step, atol=START_MOVE_SCALE * MODEL.dq_max.max() * DT)
    direction = step / np.linalg.norm(step)
    for k in range(0, cycles, max(1, cycles // 10)):  # every command along the segment's direction
        assert np.allclose(dq[k] - (dq[k] @ direction) * direction, 0.0, atol=1e-9)


def test_a_target_outside_the_joint_limits_is_bad_input():
    target = MODEL.q_max + 0.1
    with pytest.raises(BadInputError):
        StartMove(target, MODEL, DT, at_rest(PANDA.postures["elbow_up"].q))


def test_a_path_through_the_surface_is_refused_and_one_in_front_of_it_accepted():
    posture = PANDA.postures["elbow_up"]
    start = approach_start(MODEL, posture.q, posture.surface, 0.05)
    home = np.array([0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785])  # hand down: swinging it up crosses the wall
    with pytest.raises(BadInputError, match="behind the surface"):
        StartMove(start, MODEL, DT, at_rest(home), posture.surface)
    away = approach_start(MODEL, posture.q, posture.surface, 0.25)
    assert StartMove(start, MODEL, DT, at_rest(away), posture.surface).duration > 0.0
