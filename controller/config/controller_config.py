"""Controller configuration: a dataclass, loadable from a TOML or YAML file.

``ControllerConfig.from_file(path)`` reads ``.toml`` (tomllib) or ``.yaml``/``.yml`` (PyYAML);
``build.build_controller(config, robot)`` builds the ``ImpactAwareController``.
``ControllerConfig.approach(surface, speed, robot=...)`` is the default impact-approach
configuration of a robot: a fixed-base arm's, or a floating-base robot standing on its held
contacts (the G1: its centre of mass and torso held, its feet's rows, the capture region).
The file format is documented in docs/configuration.md.
"""

from __future__ import annotations

import inspect
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import pinocchio as pin

from impactqp.constraints import JUMP_MODEL_CHOICES
from impactqp.constraints.impact_model import MAX_LOOKAHEAD_DISTANCE, MAX_LOOKAHEAD_TIME
from impactqp.tasks import ORIENTATION_PARAMETERS, CentreOfMassTask, ContactApproachTask, DampingTask, FrameTask, OrientationHold
from impactqp.tasks import PostureTask, SurfaceOffsetTask

from ..model.files import read_mapping
from ..model.friction_pyramid import DEFAULT_EDGES, FrictionRows
from ..model.jump import METHODS
from ..model.max_speed import DEFAULT_IMPACT_DURATION
from ..model.postures import DEFAULT_WALL, Surface
from ..model.choice import DEFAULT_ROBOT, DEFAULT_TOOL, RobotChoice
from ..model.robot_description import RobotDescription, robot_description
from ..model.tool_description import TOOLS, tool_from_dict
from ..model import validation
from ..model.validation import BadInputError
from ..robot_config import RobotConfig

TASK_TYPES = {
    "frame": FrameTask,
    "centre_of_mass": CentreOfMassTask,
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
        validation.name_in(self.type, TASK_TYPES, "task type")


def task_of(task: TaskConfig, normal, description: RobotDescription, nv: int):
    """The task ``task`` describes for a robot of ``description`` with ``nv`` velocities, its
    robot-given parameters filled in where the configuration leaves them out: the contact
    approach's surface ``normal``, the posture's joint count, the damping's velocity count, and a
    task on the contact frame's ``orientation_*`` parameters as one ``OrientationHold``.
    BadInputError naming the parameter or value the task refuses."""
    params = dict(task.params)
    defaults = {"contact_approach": ("normal", normal), "posture": ("joints", len(description.joints)),
                "damping": ("variables", nv)}
    if task.type in defaults:
        params.setdefault(*defaults[task.type])
    kind = TASK_TYPES[task.type]
    signature = inspect.signature(kind)
    if "orientation" in signature.parameters:  # its orientation_* parameters, one OrientationHold
        if "orientation" in params:
            raise BadInputError(f"bad parameters for the {task.type} task: orientation is given as "
                                f"{', '.join(ORIENTATION_PARAMETERS)}")
        params["orientation"] = OrientationHold.taken_from(params)
    try:
        signature.bind(**params)
    except TypeError as error:
        raise BadInputError(f"bad parameters for the {task.type} task: {error}") from None
    return kind(**params)


MIN_DT, MAX_DT = 1e-4, 0.01
"""s: the control period, from 10 kHz to 100 Hz (the Panda's own loop runs at 1 kHz); the QP's
one-step discretisation of the acceleration, velocity and jerk limits holds in this range."""

MIN_LIMIT_SCALE = 0.01
"""Smallest scale of a datasheet limit: below 1 % the robot can neither move nor brake usefully."""

MAX_POSITION_MARGIN = 0.5
"""rad: a joint-limit margin beyond half a radian leaves some Panda joints no range at all."""

MAX_RETRACT_DISTANCE, MAX_HOLD_DEPTH, MAX_HOLD_SPEED = 0.5, 0.01, 0.5
"""A retract within the workspace (m), a hold depth within the compliance of a real contact (m),
and a hold speed (m/s) far below an impact's: a hold presses, it does not strike."""


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
        for name in ("position", "velocity", "torque"):
            validation.boolean(getattr(self, name), f"limits.{name}")
        for name in ("velocity_scale", "acceleration_scale", "jerk_scale", "torque_scale", "braking_fraction"):
            validation.number_in_range(
                getattr(self, name), MIN_LIMIT_SCALE, 1.0, f"limits.{name}", "(of the Franka datasheet limit)"
            )
        validation.number_in_range(self.position_margin, 0.0, MAX_POSITION_MARGIN, "limits.position_margin", "rad")


@dataclass
class ImpactConfig:
    """The impact-aware constraints (docs/qp-constraints.md).

    jump_model: 'crb', 'gm', 'classical', 'classical_normal', 'robust' (crb + gm + classical),
    or None to switch the impact-aware constraints off (the prediction in ``Command`` then uses
    ``prediction_model``). ``capture_region``: on a robot standing on held contacts, the
    predicted post-impact centre-of-mass velocity stays capturable (``CaptureRegionLimit``);
    ``foot_wrench``: there, each held contact's wrench at the impact's peak force stays in its
    friction cone and its sole (``FootWrenchLimit``, the closed form's foot slip and lift).
    ``friction`` mu in [0, 2] > 0 adds the robust friction rows (docs/frictional-impacts.md):
    ``friction_rows`` "pyramid" (``pyramid_edges`` in [3, 16] edges) or "slip" (the one-step
    preview's three: the sector of a certain slip, else the 3-edge pyramid); on held contacts
    the capture region's and the feet's rows of every edge too (``EdgeCaptureRegionLimit``,
    ``EdgeFootWrenchLimit``); 0 keeps the frictionless rows alone.
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
    capture_region: bool = True
    foot_wrench: bool = True
    friction: float = 0.0
    pyramid_edges: int = DEFAULT_EDGES
    friction_rows: str = "pyramid"

    def __post_init__(self):
        if self.jump_model is not None:
            validation.name_in(self.jump_model, JUMP_MODEL_CHOICES, "impact.jump_model")
        validation.name_in(self.prediction_model, METHODS, "impact.prediction_model")
        validation.restitution(self.restitution, "impact.restitution")
        validation.impact_duration(self.impact_duration, "impact.impact_duration")
        for name in ("post_impact_velocity", "impulsive_torque", "always_active", "capture_region", "foot_wrench"):
            validation.boolean(getattr(self, name), f"impact.{name}")
        validation.number_in_range(self.lookahead_distance, 0.0, MAX_LOOKAHEAD_DISTANCE, "impact.lookahead_distance", "m")
        validation.number_in_range(self.lookahead_time, 0.0, MAX_LOOKAHEAD_TIME, "impact.lookahead_time", "s")
        validation.number_in_range(
            self.release_speed, 0.0, validation.MAX_CONTACT_SPEED, "impact.release_speed", "m/s"
        )
        for name, field_name in (("friction", "friction"), ("pyramid_edges", "edges"), ("friction_rows", "mode")):
            try:
                FrictionRows(**{field_name: getattr(self, name)})  # each key alone, named in its error
            except BadInputError as error:
                raise BadInputError(f"impact.{name}: {error}") from None
        if self.friction > 0.0 and self.jump_model == "classical_normal":
            raise BadInputError("impact.friction: the classical_normal model has no friction rows; use 0 or another model")

    def friction_setting(self) -> FrictionRows:
        """The friction rows of the impact-aware constraints (``friction``, ``pyramid_edges``,
        ``friction_rows``)."""
        return FrictionRows(self.friction, self.pyramid_edges, self.friction_rows)


FLOATING_BASE_APPROACH = {"velocity_gain": 40.0, "normal_weight": 100.0, "orientation_weight": 1.0}
"""The hand's approach task of a floating base (docs/whole-body-qp.md): a stiffer speed law
(a 25 ms time constant, for a run-up of a few centimetres: ``controller.model.run_up``), the normal
speed weighted as the tangential motion against the balance tasks, the orientation weighted low."""

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
        validation.name_in(self.mode, POST_IMPACT_MODES, "post_impact.mode")
        validation.number_in_range(self.retract_distance, 0.0, MAX_RETRACT_DISTANCE, "post_impact.retract_distance", "m")
        validation.number_in_range(self.max_speed, 0.0, validation.MAX_CONTACT_SPEED, "post_impact.max_speed", "m/s")
        validation.number_in_range(self.hold_depth, 0.0, MAX_HOLD_DEPTH, "post_impact.hold_depth", "m")
        validation.number_in_range(self.hold_speed, 0.0, MAX_HOLD_SPEED, "post_impact.hold_speed", "m/s")
        if self.mode == "retract" and not (self.retract_distance > 0.0 and self.max_speed > 0.0):
            raise BadInputError("post_impact: a retract needs retract_distance > 0 and max_speed > 0")
        if self.mode == "hold" and not (self.hold_depth > 0.0 and self.hold_speed > 0.0):
            raise BadInputError("post_impact: a hold needs hold_depth > 0 and hold_speed > 0")


@dataclass
class SurfaceConfig:
    point: list[float] = field(default_factory=lambda: DEFAULT_WALL.point.tolist())
    normal: list[float] = field(default_factory=lambda: DEFAULT_WALL.normal.tolist())
    friction: float = DEFAULT_WALL.friction

    def __post_init__(self):
        self.surface()  # the surface's own checks, as soon as the file is read

    def surface(self) -> Surface:
        return Surface(self.point, self.normal, self.friction)

    @classmethod
    def of(cls, surface: Surface) -> SurfaceConfig:
        return cls(surface.point.tolist(), surface.normal.tolist(), float(surface.friction))


@dataclass(frozen=True)
class ApproachOptions:
    """The settings of ``ControllerConfig.approach`` beyond the surface and the speed: the robot
    (a name or a robot file), the approach, the impact model (``friction`` > 0: the robust
    friction rows, the pyramid's default edges), the solver and period, and the task weights (``posture_weight`` None: 1e-2 for a fixed base, 1e-4 for a floating base, whose
    centre of mass and torso orientation are held with ``com_weight`` and ``torso_weight``)."""

    robot: str = DEFAULT_ROBOT
    tangential_velocity: tuple = (0.0, 0.0, 0.0)
    jump_model: str | None = "crb"
    restitution: float = 0.0
    impact_duration: float = DEFAULT_IMPACT_DURATION
    solver: str = "daqp"
    dt: float = 0.001
    posture_weight: float | None = None
    com_weight: float = 10.0
    torso_weight: float = 10.0
    always_active: bool = False
    friction: float = 0.0


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
    robot: str = DEFAULT_ROBOT
    tool: str | dict = DEFAULT_TOOL
    libfranka: RobotConfig = field(default_factory=RobotConfig)

    def __post_init__(self):
        validation.number_in_range(self.dt, MIN_DT, MAX_DT, "dt", "s (10 kHz to 100 Hz)")
        if not isinstance(self.solver, str) or not self.solver:
            raise BadInputError(f"solver must be a QP solver name, got {self.solver!r}")
        if not isinstance(self.robot, str):
            raise BadInputError(f"robot must be a robot name or a robot file, got {self.robot!r}")
        if not isinstance(self.tool, (str, dict)):
            raise BadInputError(f"tool must be a tool name, a tool file or a [tool] table, got {self.tool!r}")
        choice = self.choice  # the robot's and the tool's own checks, as soon as the file is read
        if self.libfranka != RobotConfig():  # a [libfranka] table given: one value per joint of this robot
            self.libfranka.check_joints(len(choice.robot.joints))

    def check_tasks(self) -> None:
        """Every task built once for the robot (``task_of``; ``from_dict`` and ``from_file``, as
        soon as the file is read; ``build_controller`` builds them again): a bad parameter or value
        is bad input naming the task (``tasks[i]``)."""
        description = self.choice.robot
        nv = len(description.joints) + (pin.JointModelFreeFlyer().nv if description.floating else 0)
        normal = self.surface.surface().normal
        for index, task in enumerate(self.tasks):
            try:
                task_of(task, normal, description, nv)
            except BadInputError as error:
                raise BadInputError(f"tasks[{index}]: {error}") from None

    @property
    def choice(self) -> RobotChoice:
        """The robot and the tool: ``robot`` by name or robot file, ``tool`` by built-in name, file
        or table (the keys of a tool file, docs/robots.md); a fixed-base robot's (this is an arm's
        controller); built once per (robot, tool) value."""
        key = (self.robot, self.tool)
        cached = self.__dict__.get("_choice")
        if cached is not None and cached[0] == key:
            return cached[1]
        if isinstance(self.tool, dict):
            try:
                tool = tool_from_dict(self.tool)
            except BadInputError as error:
                raise BadInputError(f"[tool]: {error}") from None
        else:
            tool = self.tool
        choice = RobotChoice.of(self.robot, tool)
        if choice.robot.floating and (self.limits.torque or self.impact.impulsive_torque):
            key = "limits.torque" if self.limits.torque else "impact.impulsive_torque"
            raise BadInputError(
                f"{key}: the {choice.robot.name} has a floating base, whose joint torques depend on its contact "
                f"wrenches, which the QP does not carry; set {key} = false"
            )
        self.__dict__["_choice"] = (key, choice)
        return choice

    def for_choice(self, choice: RobotChoice) -> ControllerConfig:
        """This configuration for ``choice``'s robot and tool, as a new configuration whose
        ``choice`` is ``choice`` itself (its model and solved postures are shared, not rebuilt)."""
        config = replace(self, robot=choice.robot_setting, tool=choice.tool_setting)
        config.__dict__["_choice"] = ((config.robot, config.tool), choice)
        return config

    @classmethod
    def approach(cls, surface: Surface = DEFAULT_WALL, speed: float = 0.1, **options) -> ControllerConfig:
        """The default impact approach of ``robot``: a contact-approach task towards ``surface``
        at the normal ``speed`` (plus ``tangential_velocity``), holding orientation and
        tangential motion; a weak posture task (null-space), a damping task; every joint limit;
        and the impact-aware post-impact-velocity and impulsive-torque constraints with
        ``jump_model`` (None switches them off). A floating-base robot also holds its centre of
        mass and its torso's orientation (``frame = "torso"``), keeps its held contacts (their
        rows are always added) and its post-impact centre-of-mass velocity capturable; it has
        no torque rows, and its hand's task is :data:`FLOATING_BASE_APPROACH`. ``options`` are the
        fields of :class:`ApproachOptions`."""
        o = ApproachOptions(**options)
        floating = robot_description(o.robot).floating
        approach = TaskConfig(
            "contact_approach",
            {"speed": validation.number(speed, "the approach speed"),
             "tangential_velocity": validation.finite_vector(o.tangential_velocity, 3, "the tangential velocity").tolist(),
             **(FLOATING_BASE_APPROACH if floating else {})},
        )
        balance = [
            TaskConfig("centre_of_mass", {"weight": [float(o.com_weight)] * 3}),
            TaskConfig("frame", {"position_weight": 0.0, "orientation_weight": float(o.torso_weight), "frame": "torso"}),
        ] if floating else []
        posture_weight = o.posture_weight if o.posture_weight is not None else (1e-4 if floating else 1e-2)
        return cls(
            dt=o.dt,
            solver=o.solver,
            tasks=[approach, *balance, TaskConfig("posture", {"weight": posture_weight}), TaskConfig("damping", {})],
            limits=LimitsConfig(torque=not floating),
            impact=ImpactConfig(
                jump_model=o.jump_model,
                restitution=o.restitution,
                impact_duration=o.impact_duration,
                always_active=o.always_active,
                impulsive_torque=not floating,
                friction=o.friction,
            ),
            surface=SurfaceConfig.of(surface),
            robot=o.robot,
        )

    @classmethod
    def from_dict(cls, data: dict) -> ControllerConfig:
        """The configuration of a parsed file; every key and value is checked (bad input:
        ``BadInputError``, one line naming the key)."""
        data = dict(validation.table(data, "the configuration"))
        unknown = set(data) - {f.name for f in fields(cls)}
        if unknown:
            raise BadInputError(f"unknown configuration keys: {', '.join(sorted(map(str, unknown)))}")
        tasks = data.pop("tasks", None) or []
        if not isinstance(tasks, list):
            raise BadInputError(f"tasks must be a list of tables, got {tasks!r}")
        parsed_tasks = []
        for index, entry in enumerate(tasks):
            entry = dict(validation.table(entry, f"tasks[{index}]"))
            if "type" not in entry:
                raise BadInputError(f"tasks[{index}] needs a 'type'")
            task_type = entry.pop("type")
            params = validation.table(entry.pop("params", None) or {}, f"tasks[{index}].params")
            parsed_tasks.append(TaskConfig(task_type, dict(params) | entry))
        sections = {
            "limits": LimitsConfig, "impact": ImpactConfig, "surface": SurfaceConfig, "post_impact": PostImpactConfig,
            "libfranka": RobotConfig,
        }
        parsed = {name: _section(kind, data.pop(name, None), name) for name, kind in sections.items()}
        config = cls(tasks=parsed_tasks, **parsed, **data)
        config.check_tasks()
        return config

    @classmethod
    def from_file(cls, path: str | Path) -> ControllerConfig:
        """Read a ``.toml``, ``.yaml`` or ``.yml`` file. An unreadable, undecodable, malformed or
        out-of-range file is bad input (``BadInputError``) whose one line names the file."""
        path = Path(path)
        if path.suffix.lower() not in (".toml", ".yaml", ".yml"):
            raise BadInputError(f"unsupported configuration file {path.name}: use .toml, .yaml or .yml")
        data = read_mapping(path, "file")
        tool = data.get("tool")
        if isinstance(tool, str) and tool not in TOOLS and not Path(tool).is_absolute():
            data["tool"] = str(path.parent / tool)  # a tool file beside the configuration
        try:
            return cls.from_dict(data)
        except BadInputError as error:
            raise BadInputError(f"{path}: {error}") from None

    def to_dict(self) -> dict:
        """Plain data (tasks flattened), such that ``from_dict(to_dict())`` round-trips."""
        data = asdict(self)
        data["tasks"] = [{"type": t.type, **t.params} for t in self.tasks]
        return data


def _section(kind, values, name: str):
    if values is None:
        return kind()
    unknown = set(validation.table(values, f"[{name}]")) - {f.name for f in fields(kind)}
    if unknown:
        raise BadInputError(f"unknown keys in [{name}]: {', '.join(sorted(map(str, unknown)))}")
    return kind(**values)
