"""Named postures solved for any tool: the tool's contact point on the same wall point, its axis
along -n, the elbow and wrist arrangement kept."""

import numpy as np
import pytest
from conftest import ARMS

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.tool_description import TOOLS
from impactqp.controller.model.tool_postures import tool_posture


@pytest.mark.parametrize("robot", ARMS)
@pytest.mark.parametrize("tool", list(TOOLS))
def test_each_named_posture_puts_the_tool_on_the_same_wall_point(robot, tool):
    model, reference = RobotModel(robot, tool), RobotModel(robot)
    for name, named in ROBOTS[robot].postures.items():
        solved = tool_posture(model, name)
        terms = model.terms(solved.q)  # inside the limits and non-singular, or it raises
        np.testing.assert_allclose(terms.contact_point, reference.contact_point(named.q), atol=1e-5)
        np.testing.assert_allclose(terms.contact_rotation[:, 2], -named.surface.normal, atol=1e-4)
        # the same arrangement: every joint keeps its side (a joint near zero may cross it)
        assert np.all((np.sign(solved.q) == np.sign(named.q)) | (np.abs(named.q) < 0.1))


def test_the_default_tool_keeps_the_named_posture():
    model = RobotModel("fr3")
    assert tool_posture(model, "elbow_up") is ROBOTS["fr3"].postures["elbow_up"]
