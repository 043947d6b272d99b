"""The standing G1's default whole-body controller (controller/qp/whole_body_setup.py)."""

import pytest
from whole_body_states import controller, robot

from impactqp.controller.model.validation import BadInputError
from impactqp.tasks import DampingTask


def test_setup_assembles_the_tasks_and_constraints_and_refuses_a_bad_controller():
    c = controller("staggered", method="gm")
    names = [x.name for x in c.constraints]
    assert names == [
        "joint_acceleration_limit", "joint_position_limit", "joint_velocity_limit", "held_contacts",
        "post_impact_velocity[gm]", "capture_region[gm]",
    ]
    assert [t.name for t in c.tasks] == ["contact_approach", "com", "frame[torso]", "posture", "damping"]
    with pytest.raises(BadInputError):
        type(c)(robot(), [], c.constraints, 0.001)
    with pytest.raises(BadInputError):
        type(c)(robot(), [DampingTask(variables=robot().nv)], c.constraints + c.constraints[-1:], 0.001)
