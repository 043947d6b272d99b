"""The named impact postures for any tool: the same wall point, the same arrangement.

A robot's named postures (``RobotDescription.postures``) put the ``impact_tip`` tool's contact
point on the wall with the tool axis (the contact frame's z) along -n. For another tool,
:func:`tool_posture` solves the same task, the tool's contact point on that same wall point with
its axis along -n, by inverse kinematics seeded with the named posture, so the elbow and wrist
keep their arrangement.
"""

from __future__ import annotations

import numpy as np

from .inverse_kinematics import contact_posture
from .postures import ImpactPosture
from .robot import RobotModel
from .tool_description import TOOLS
from .validation import BadInputError


def tool_posture(model: RobotModel, name: str) -> ImpactPosture:
    """The named posture ``name`` of ``model``'s robot, solved for ``model``'s tool."""
    named = model.description.posture(name)
    default = TOOLS["impact_tip"]
    if model.tool.frame == default.frame and np.array_equal(model.tool.contact_point, default.contact_point):
        return named
    point = RobotModel(model.description, default).contact_point(named.q)
    solved = contact_posture(model, point, named.surface.normal, named.q)
    if not solved.reachable:
        raise BadInputError(
            f"the {model.description.name} cannot put the tool {model.tool.name!r} on the wall point of "
            f"posture {name!r} (position error {solved.position_error:.2g} m)"
        )
    return ImpactPosture(name, solved.q, f"{named.description}; solved for the tool {model.tool.name}", named.surface)
