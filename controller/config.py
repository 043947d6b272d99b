"""Controller configuration: a dataclass, loadable from a TOML or YAML file.

``ControllerConfig.from_file(path)`` reads ``.toml`` (tomllib) or ``.yaml``/``.yml`` (PyYAML);
``build_controller(config, robot)`` builds the :class:`ImpactAwareController`.
``ControllerConfig.approach(surface, speed)`` is the default impact-approach configuration.
The file format is documented in the project README (section "Controller configuration").
"""

from __future__ import annotations

import math

import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from impactqp.constraints import (
    AccelerationLimit,
    ImpactModel,
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
    jump_model_names,
)
from impactqp.tasks import ContactApproachTask, DampingTask, FrameTask, PostureTask, SurfaceOffsetTask

from .model.max_speed import DEFAULT_IMPACT_DURATION
from .model.postures import DEFAULT_WALL, Surface
from .qp import ImpactAwareController
from .model.robot import PandaModel
from .model import validation
from .model.validation import BadInputError

TASK_TYPES = {
    "frame": FrameTask,
    "contact_approach": ContactApproachTask,
    "posture": PostureTask,
    "damping": DampingTask,
    "surface_offset": SurfaceOffsetTask,
}


@dataclass
class TaskConfig:
    """One task: its ``type`` (a key of TASK_TYPES) and the keyword arguments of its class.

    The contact-approach task takes its ``normal`` from the configured surface.
    """

    type: str
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.type not in TASK_TYPES:
            raise BadInputError(f"unknown task type {self.type!r}; choose from {', '.join(TASK_TYPES)}")


@dataclass
class LimitsConfig:
    """Which joint-limit constraints apply, and their scaling (1.0 = Franka datasheet).

    The acceleration and jerk limits always apply.
    """

    position: bool = True
    velocity: bool = True
    torque: bool = True
    velocity_scale: float = 1.0
    acceleration_scale: float = 1.0
    jerk_scale: float = 1.0
    torque_scale: float = 1.0
    braking_fraction: float = 0.5
    position_margin: float = 0.0

    def __post_init__(self):
        for name in ("velocity_scale", "acceleration_scale", "jerk_scale", "torque_scale", "braking_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 1.0):
                raise BadInputError(f"limits.{name} = {value} must lie in (0, 1]: the datasheet limits are the robot's")
        if not (math.isfinite(self.position_margin) and self.position_margin >= 0.0):
            raise BadInputError(f"limits.position_margin = {self.position_margin} rad must be >= 0")


@dataclass
class ImpactConfig:
    """The impact-aware constraints (docs/qp-constraints.md).

    jump_model: 'crb', 'gm', 'classical', 'classical_normal', 'robust' (crb + gm + classical),
    or None to switch the impact-aware constraints off (the prediction in ``Command`` then uses
    ``prediction_model``).
    """

    jump_model: str | None = "crb"
    restitution: float = 0.0
    impact_duration: float = DEFAULT_IMPACT_DURATION
    post_impact_velocity: bool = True
    impulsive_torque: bool = True
    lookahead_distance: float = 0.10
    lookahead_time: float = 0.30
    release_speed: float = 0.02
    always_active: bool = False
    prediction_model: str = "crb"

    def __post_init__(self):
        validation.restitution(self.restitution, "impact.restitution")
        validation.impact_duration(self.impact_duration, "impact.impact_duration")
        for name in ("lookahead_distance", "lookahead_time", "release_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise BadInputError(f"impact.{name} = {value} must be a finite number >= 0")


POST_IMPACT_MODES = ("retract", "hold", "continue")


@dataclass
class PostImpactConfig:
    """What the controller does once the impact is detected (``docs/robot-loop.md``).

    ``retract``: pull the contact point back along the surface normal to ``retract_distance``
    (m) from the surface, at most at ``max_speed`` (m/s) (``tasks.SurfaceOffsetTask``);
    ``hold``: come back to the surface and press on it: the target is at depth ``hold_depth``
    (m) behind the surface, approached at most at ``hold_speed`` (m/s), so once in contact the
    commanded normal velocity saturates at ``hold_speed`` and the normal force is the joint
    servo's bounded response to it (proportional to ``hold_speed`` while position_gain x
    hold_depth >= hold_speed); ``continue``: keep the approach tasks. In every mode the
    impact-aware constraints are off after the impact and every joint limit still applies.
    """

    mode: str = "retract"
    retract_distance: float = 0.05
    max_speed: float = 0.1
    hold_depth: float = 0.002
    hold_speed: float = 0.02

    def __post_init__(self):
        if self.mode not in POST_IMPACT_MODES:
            raise ValueError(f"post_impact.mode = {self.mode!r}; choose from {', '.join(POST_IMPACT_MODES)}")
        for name in ("retract_distance", "max_speed", "hold_depth", "hold_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"post_impact.{name} = {value} must be a finite number >= 0")
        if self.mode == "retract" and not (self.retract_distance > 0.0 and self.max_speed > 0.0):
            raise ValueError("post_impact: a retract needs retract_distance > 0 and max_speed > 0")
        if self.mode == "hold" and not (self.hold_depth > 0.0 and self.hold_speed > 0.0):
            raise ValueError("post_impact: a hold needs hold_depth > 0 and hold_speed > 0")


@dataclass
class SurfaceConfig:
    point: list[float] = field(default_factory=lambda: DEFAULT_WALL.point.tolist())
    normal: list[float] = field(default_factory=lambda: DEFAULT_WALL.normal.tolist())
    friction: float = DEFAULT_WALL.friction

    def surface(self) -> Surface:
        return Surface(np.asarray(self.point, float), np.asarray(self.normal, float), self.friction)

    @classmethod
    def of(cls, surface: Surface) -> SurfaceConfig:
        return cls(surface.point.tolist(), surface.normal.tolist(), float(surface.friction))


@dataclass
class ControllerConfig:
    """Everything ``build_controller`` needs: tasks, limits, impact model, surface, solver."""

    dt: float = 0.001
    solver: str = "daqp"
    tasks: list[TaskConfig] = field(default_factory=list)
    limits: LimitsConfig = field(default_factory=LimitsConfig)
    impact: ImpactConfig = field(default_factory=ImpactConfig)
    surface: SurfaceConfig = field(default_factory=SurfaceConfig)
    post_impact: PostImpactConfig = field(default_factory=PostImpactConfig)

    @classmethod
    def approach(
        cls,
        surface: Surface = DEFAULT_WALL,
        speed: float = 0.1,
        tangential_velocity=(0.0, 0.0, 0.0),
        jump_model: str | None = "crb",
        restitution: float = 0.0,
        impact_duration: float = DEFAULT_IMPACT_DURATION,
        solver: str = "daqp",
        dt: float = 0.001,
        posture_weight: float = 1e-2,
        always_active: bool = False,
    ) -> ControllerConfig:
        """The default impact approach: a contact-approach task towards ``surface`` at the
        normal ``speed`` (plus ``tangential_velocity``), holding orientation and tangential
        motion; a weak posture task (null-space), a damping task; every joint limit; and the
        impact-aware post-impact-velocity and impulsive-torque constraints with ``jump_model``
        (None switches them off)."""
        return cls(
            dt=dt,
            solver=solver,
            tasks=[
                TaskConfig(
                    "contact_approach",
                    {"speed": float(speed), "tangential_velocity": [float(v) for v in tangential_velocity]},
                ),
                TaskConfig("posture", {"weight": posture_weight}),
                TaskConfig("damping", {}),
            ],
            impact=ImpactConfig(
                jump_model=jump_model,
                restitution=restitution,
                impact_duration=impact_duration,
                always_active=always_active,
            ),
            surface=SurfaceConfig.of(surface),
        )

    @classmethod
    def from_dict(cls, data: dict) -> ControllerConfig:
        data = dict(data)
        unknown = set(data) - {f.name for f in fields(cls)}
        if unknown:
            raise BadInputError(f"unknown configuration keys: {', '.join(sorted(unknown))}")
        tasks = []
        for entry in data.pop("tasks", []):
            entry = dict(entry)
            if "type" not in entry:
                raise BadInputError(f"a task needs a 'type': {entry}")
            task_type = entry.pop("type")
            tasks.append(TaskConfig(task_type, entry.pop("params", {}) | entry))
        sections = {
            "limits": LimitsConfig, "impact": ImpactConfig, "surface": SurfaceConfig, "post_impact": PostImpactConfig,
        }
        parsed = {name: _section(kind, data.pop(name, {}), name) for name, kind in sections.items()}
        return cls(tasks=tasks, **parsed, **data)

    @classmethod
    def from_file(cls, path: str | Path) -> ControllerConfig:
        path = Path(path)
        if path.suffix == ".toml":
            with path.open("rb") as file:
                data = tomllib.load(file)
        elif path.suffix in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(path.read_text()) or {}
        else:
            raise BadInputError(f"unsupported configuration file {path.name}: use .toml, .yaml or .yml")
        return cls.from_dict(data)

    def to_dict(self) -> dict:
        """Plain data (tasks flattened), such that ``from_dict(to_dict())`` round-trips."""
        data = asdict(self)
        data["tasks"] = [{"type": t.type, **t.params} for t in self.tasks]
        return data


def _section(kind, values: dict, name: str):
    if values is None:
        return kind()
    unknown = set(values) - {f.name for f in fields(kind)}
    if unknown:
        raise BadInputError(f"unknown keys in [{name}]: {', '.join(sorted(unknown))}")
    return kind(**values)


def build_controller(config: ControllerConfig, robot: PandaModel | None = None) -> ImpactAwareController:
    """The controller described by ``config`` (a fresh PandaModel when ``robot`` is None)."""
    robot = PandaModel() if robot is None else robot
    surface = config.surface.surface()
    limits, impact = config.limits, config.impact

    tasks = []
    for task in config.tasks:
        params = dict(task.params)
        if task.type == "contact_approach":
            params.setdefault("normal", surface.normal)
        try:
            tasks.append(TASK_TYPES[task.type](**params))
        except TypeError as error:
            raise BadInputError(f"bad parameters for the {task.type} task: {error}") from None

    dq_max = robot.dq_max * limits.velocity_scale
    tau_max = robot.tau_max * limits.torque_scale
    ddq_max = robot.ddq_max * limits.acceleration_scale
    dddq_max = robot.dddq_max * limits.jerk_scale
    constraints = [AccelerationLimit()]
    if limits.position:
        constraints.append(
            PositionLimit(robot.q_min, robot.q_max, ddq_max, limits.braking_fraction, limits.position_margin)
        )
    if limits.velocity:
        constraints.append(VelocityLimit(dq_max))
    if limits.torque:
        constraints.append(TorqueLimit(tau_max))

    def impact_model(name: str) -> ImpactModel:
        return ImpactModel(
            surface,
            name,
            impact.restitution,
            impact.lookahead_distance,
            impact.lookahead_time,
            impact.release_speed,
            impact.always_active,
        )

    models = [impact_model(name) for name in jump_model_names(impact.jump_model)] if impact.jump_model else []
    for model in models:
        if impact.post_impact_velocity:
            constraints.append(PostImpactVelocityLimit(model, dq_max))
        if impact.impulsive_torque:
            constraints.append(ImpulsiveTorqueLimit(model, tau_max, dq_max, impact.impact_duration))
    prediction = models[0] if models else impact_model(impact.prediction_model)
    return ImpactAwareController(
        robot, tasks, constraints, config.dt, config.solver, prediction,
        acceleration_limit=ddq_max, jerk_limit=dddq_max,
    )


def post_impact_config(config: ControllerConfig) -> ControllerConfig:
    """The configuration of the controller after the impact (``config.post_impact``): the
    impact-aware constraints off; for ``retract`` and ``hold`` the contact-approach and frame
    tasks replaced by one ``surface_offset`` task, the other tasks and every limit kept."""
    post = config.post_impact
    impact = replace(config.impact, jump_model=None)
    if post.mode == "continue":
        return replace(config, impact=impact)
    if post.mode == "retract":
        offset, speed = post.retract_distance, post.max_speed
    else:
        offset, speed = -post.hold_depth, post.hold_speed
    surface = config.surface
    offset_task = TaskConfig(
        "surface_offset",
        {"normal": surface.normal, "surface_point": surface.point, "offset": offset, "max_speed": speed},
    )
    kept = [t for t in config.tasks if t.type not in ("contact_approach", "frame")]
    return replace(config, tasks=[offset_task, *kept], impact=impact)
