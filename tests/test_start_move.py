"""The move to the start posture: jerk-limited straight joint segments inside the scaled limits,
ending at rest on the target; a path that keeps the tool ``START_CLEARANCE`` in front of the
surface (through a retreat along the normal when the straight one would not), checked on a
densely sampled path; a target outside the joint limits, or a start that no path reaches in front
of the surface, is refused before anything moves."""

import numpy as np
import pytest
from hypothesis import assume, given, settings

from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA, ROBOTS
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.runtime import start_move
from impactqp.controller.runtime.interface import RobotState
from impactqp.controller.runtime.start_move import START_CLEARANCE, START_MOVE_SCALE, StartMove
from impactqp.controller.model.inverse_kinematics import approach_start
from conftest import JOINTS, joint_positions

pytest.importorskip("ruckig", reason="ruckig is not installed: pip install -e '.[franka]'")

MODEL = PandaModel()
DT = 1e-3
FRANKY_SIM_HOME = np.array([0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785])
"""franky-sim's initial posture (``franky_sim.constants.DEFAULT_INITIAL_JOINT_POS``): the hand
down, its tool 45.6 mm in front of the default wall at x = 0.6 m."""
DENSE = 20_000  # samples of the planned path in the clearance check of the tests


def at_rest(q):
    return RobotState(0.0, np.asarray(q, float), np.zeros(JOINTS), np.zeros(JOINTS))


def commands(move):
    cycles = int(np.ceil(move.duration / DT)) + 1
    return np.array([move.step(None).dq_cmd for _ in range(cycles)])


def assert_within_the_scaled_limits_to_rest_at(dq, model, q0, target):
    assert np.allclose(dq[-1], 0.0, atol=1e-12)
    assert np.all(np.abs(dq) <= START_MOVE_SCALE * model.dq_max * (1 + 1e-9))
    ddq = np.diff(np.vstack([np.zeros(JOINTS), dq]), axis=0) / DT
    assert np.all(np.abs(ddq) <= START_MOVE_SCALE * model.ddq_max * (1 + 1e-6))
    jerk = np.diff(np.vstack([np.zeros((2, JOINTS)), dq]), n=2, axis=0) / DT**2
    assert np.all(np.abs(jerk) <= START_MOVE_SCALE * model.dddq_max * (1 + 1e-6))
    travelled = dq.sum(axis=0) * DT  # the commanded positions, integrated over the periods
    assert np.allclose(travelled, target - q0, atol=START_MOVE_SCALE * model.dq_max.max() * DT)


def clearance_from_geometry(model, surface, q) -> float:
    """The tool's clearance from first principles: the contact point's distance n . (p - p_s),
    and, for the sphere tool, its centre's distance minus its radius."""
    frame = model.contact_frame(q)
    centre = frame.translation + frame.rotation @ (model.tool.geometry.centre - model.tool.contact_point)
    return min(surface.signed_distance(frame.translation), surface.signed_distance(centre) - model.tool.geometry.radius)


@settings(max_examples=10, deadline=None)
@given(joint_positions(0.2), joint_positions(0.2))
def test_the_commands_follow_a_straight_path_inside_the_limits_to_rest_at_the_target(q0, target):
    assume(np.max(np.abs(target - q0)) > 1e-3)
    move = StartMove(target, MODEL, DT, at_rest(q0))
    dq = commands(move)
    assert_within_the_scaled_limits_to_rest_at(dq, MODEL, q0, target)
    step = target - q0
    direction = step / np.linalg.norm(step)
    for k in range(0, len(dq), max(1, len(dq) // 10)):  # every command along the segment's direction
        assert np.allclose(dq[k] - (dq[k] @ direction) * direction, 0.0, atol=1e-9)


def test_a_target_outside_the_joint_limits_is_bad_input():
    target = MODEL.q_max + 0.1
    with pytest.raises(BadInputError):
        StartMove(target, MODEL, DT, at_rest(PANDA.postures["elbow_up"].q))


@pytest.mark.parametrize("robot", ["fr3", "panda"])
def test_from_franky_sims_home_every_start_posture_is_reached_with_the_tool_in_front_of_the_wall(robot):
    model = RobotModel(robot)  # the impact_tip sphere
    assert model.tool.geometry.radius > 0.0
    for name, posture in ROBOTS[robot].postures.items():
        target = approach_start(model, posture.q, posture.surface, 0.05)
        move = StartMove(target, model, DT, at_rest(FRANKY_SIM_HOME), posture.surface)
        path = [move.position(t) for t in np.linspace(0.0, move.duration, DENSE)]
        clearance = min(clearance_from_geometry(model, posture.surface, q) for q in path)
        assert clearance >= START_CLEARANCE, (name, clearance)
        assert np.allclose(path[-1], target, atol=1e-12)
        assert_within_the_scaled_limits_to_rest_at(commands(move), model, FRANKY_SIM_HOME, target)
    # elbow_up's straight segment passes the tool behind the wall: its path retreats first
    up = ROBOTS[robot].postures["elbow_up"]
    move = StartMove(approach_start(model, up.q, up.surface, 0.05), model, DT, at_rest(FRANKY_SIM_HOME), up.surface)
    assert move.path.retreat > 0.0 and len(move.segments) == 2


def test_a_start_behind_the_surface_or_without_a_path_in_front_is_refused_with_the_margin(monkeypatch):
    posture = PANDA.postures["elbow_up"]
    target = approach_start(MODEL, posture.q, posture.surface, 0.05)
    nearer = Surface(posture.surface.point + 0.1 * posture.surface.normal, posture.surface.normal)  # 5 cm behind it
    with pytest.raises(BadInputError, match=r"the start posture puts the tool -\d+ mm .*margin of 20 mm"):
        StartMove(target, MODEL, DT, at_rest(approach_start(MODEL, posture.q, nearer, 0.25)), nearer)
    monkeypatch.setattr(start_move, "RETREATS", ())  # only the straight segment, which crosses the wall
    with pytest.raises(BadInputError, match=r"keeps the tool 20 mm in front.*comes within -\d+ mm"):
        StartMove(target, MODEL, DT, at_rest(FRANKY_SIM_HOME), posture.surface)
    away = approach_start(MODEL, posture.q, posture.surface, 0.25)
    move = StartMove(target, MODEL, DT, at_rest(away), posture.surface)
    assert move.path.retreat == 0.0 and move.path.clearance >= START_CLEARANCE
