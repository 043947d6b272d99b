"""The standing robot's balance after the impact (controller/config/post_impact_balance.py): the
CoM task's target over the centre of the support polygon, its PD and weight, the hand's weight."""

import numpy as np
import pytest

from impactqp.controller.config import ControllerConfig, balance_after_impact, build_controller
from impactqp.controller.config import post_impact_balance as balance
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture, support_polygon
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.tasks import CentreOfMassTask, ContactApproachTask

NORMAL = np.array([-1.0, 0.0, 0.0])


def task_of(controller, kind):
    return next(t for t in controller.tasks if isinstance(t, kind))


@pytest.mark.parametrize("stance", ["parallel", "staggered", "close"])
def test_the_com_target_moves_over_the_polygon_s_centre_and_the_hand_steps_back(stance):
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES[stance])
    wall = Surface(robot.terms(q).contact_point - 0.02 * NORMAL, NORMAL)
    controller = build_controller(ControllerConfig.approach(wall, 0.3, robot="g1"), robot, q)
    controller.step(q, np.zeros(robot.nv))
    com, hand = task_of(controller, CentreOfMassTask), task_of(controller, ContactApproachTask)
    height, hand_weight = com.target[2], hand.weight.copy()
    balance_after_impact(controller)
    centre = support_polygon(robot, controller.memory.q_cmd).mean(axis=0)
    np.testing.assert_allclose(com.target[:2], centre, atol=1e-12)
    assert com.target[2] == height
    assert com.stiffness == balance.COM_STIFFNESS and com.damping == pytest.approx(2 * np.sqrt(balance.COM_STIFFNESS))
    assert np.all(com.weight == balance.COM_WEIGHT) and com.weight.min() > hand.weight.max()
    np.testing.assert_allclose(hand.weight, balance.HAND_SCALE * hand_weight)


def test_a_fixed_base_controller_is_left_alone():
    robot = PandaModel()
    controller = build_controller(ControllerConfig.approach(DEFAULT_WALL, 0.2), robot)
    weights = [np.copy(t.weight) for t in controller.tasks]
    balance_after_impact(controller)
    for task, weight in zip(controller.tasks, weights):
        np.testing.assert_array_equal(task.weight, weight)
