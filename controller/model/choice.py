"""The robot and the tool a command, a configuration or a dataset works with (``--robot``,
``--tool``; docs/robots.md).

A :class:`RobotChoice` is the one value passed down the layers instead of two names: it builds
the model (``RobotModel``) and knows the robot's named impact postures solved for the tool
(``tool_postures.tool_posture``). It is small, frozen and picklable, so a process pool's workers
receive it and build their own model and scene from it.

A floating-base robot (``robot.floating``: the G1) carries no tool: it hits with its own contact
point (its description's ``contact``), its ``tool`` is None, its model is
``RobotModel`` with a free-flyer root and its postures are its description's ``stances``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from .postures import ImpactPosture
from .robot import RobotModel
from .robot_description import PANDA, ROBOTS, RobotDescription, robot_description
from .tool_description import TOOLS, ToolDescription, tool_description
from .tool_postures import tool_posture
from . import validation
from .validation import BadInputError

DEFAULT_ROBOT = PANDA.name
DEFAULT_TOOL = "impact_tip"


@dataclass(frozen=True, eq=False)
class RobotChoice:
    """A robot description and the tool it carries (default: the Panda with ``impact_tip``; a
    fixed-base robot given no tool carries ``impact_tip``, a floating-base robot carries none:
    ``tool`` None, anything else is bad input)."""

    robot: RobotDescription = PANDA
    tool: ToolDescription | None = None

    def __post_init__(self):
        if self.robot.floating and self.tool is not None:
            raise BadInputError(_no_tool(self.robot, self.tool.name))
        if not self.robot.floating and self.tool is None:
            object.__setattr__(self, "tool", TOOLS[DEFAULT_TOOL])

    @classmethod
    def of(
        cls,
        robot: str | Path | RobotDescription = DEFAULT_ROBOT,
        tool: str | Path | ToolDescription = DEFAULT_TOOL,
    ) -> RobotChoice:
        """The choice of a robot name, file (or description) and a tool name, file (or
        description). A floating-base robot takes only the default ``tool`` (what a command line
        passes when no tool is given), which it ignores: it carries none; any other tool is bad
        input (one line)."""
        description = robot_description(robot)
        if not description.floating:
            return cls(description, tool_description(tool))
        if not (isinstance(tool, str) and tool == DEFAULT_TOOL):
            raise BadInputError(_no_tool(description, getattr(tool, "name", str(tool))))
        return cls(description)

    @property
    def is_default(self) -> bool:
        """Whether this is the Panda with the built-in ``impact_tip``."""
        return self.robot.name == DEFAULT_ROBOT and _tool_dict(self.tool) == TOOLS[DEFAULT_TOOL].as_dict()

    def same_as(self, other: RobotChoice) -> bool:
        """Whether ``other`` names the same robot and an identical tool description (or no tool)."""
        return self.robot_setting == other.robot_setting and _tool_dict(self.tool) == _tool_dict(other.tool)

    @property
    def robot_setting(self) -> str:
        """The robot as a configuration holds it: a built-in's name, else its file's path."""
        builtin = ROBOTS.get(self.robot.name)
        if builtin is self.robot or self.robot.source is None:
            return self.robot.name
        return str(self.robot.source)

    @property
    def tool_setting(self) -> str | dict:
        """The tool as a configuration holds it: a built-in's name, else its full description (a
        floating-base robot, which carries none: the default name, which ``of`` ignores for it)."""
        if self.tool is None:
            return DEFAULT_TOOL
        builtin = TOOLS.get(self.tool.name)
        return self.tool.name if builtin is not None and builtin.as_dict() == self.tool.as_dict() else self.tool.as_dict()

    def model(self) -> RobotModel:
        """A new model of the robot with the tool (each caller owns its Pinocchio data)."""
        return RobotModel(self.robot, self.tool)

    @cached_property
    def shared_model(self) -> RobotModel:
        """The one model of this choice in a process, built on first use, for the callers of one
        request that run one after the other (the postures, the start's check, a search).
        It is not pickled: a worker process builds its own."""
        return self.model()

    def __getstate__(self) -> dict:
        return {key: value for key, value in self.__dict__.items() if key != "shared_model"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    @cached_property
    def postures(self) -> dict[str, ImpactPosture]:
        """The robot's named postures, solved for the tool (computed once per choice)."""
        return {name: tool_posture(self.shared_model, name) for name in self.robot.postures}

    def posture(self, name: str) -> ImpactPosture:
        """The named posture ``name``; bad input naming the known ones otherwise."""
        if name not in self.robot.postures:
            raise BadInputError(
                f"unknown posture {name!r} for the {self.robot.name}; known: {', '.join(self.robot.postures)}"
            )
        return self.postures[name]

    def check_postures(self, names) -> tuple[str, ...]:
        """``names`` as a tuple after checking each is a named posture of the robot, once."""
        names = tuple(names)
        validation.distinct_names(names, "the postures")
        for name in names:
            if name not in self.robot.postures:
                raise BadInputError(
                    f"unknown posture {name!r} for the {self.robot.name}; known: {', '.join(self.robot.postures)}"
                )
        return names

    def __repr__(self) -> str:
        return f"RobotChoice(robot={self.robot.name!r}, tool={None if self.tool is None else self.tool.name!r})"


def _no_tool(robot: RobotDescription, tool: str) -> str:
    contact = "" if robot.contact is None else f" {robot.contact.name}"
    return f"the {robot.name} has a floating base and carries no tool (it hits with its own contact point{contact}), not {tool!r}"


def _tool_dict(tool: ToolDescription | None) -> dict | None:
    return None if tool is None else tool.as_dict()


DEFAULT_CHOICE = RobotChoice()
"""The Panda with the ``impact_tip``: what every command used before ``--robot``/``--tool``."""
