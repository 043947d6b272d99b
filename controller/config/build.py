"""The controller a configuration describes (``build_controller``) and the configuration after the
impact (``post_impact_config``)."""

from __future__ import annotations

from dataclasses import replace

from impactqp.constraints import (
    AccelerationLimit,
    ActivationRule,
    CaptureRegionLimit,
    EdgeCaptureRegionLimit,
    EdgeFootWrenchLimit,
    ExpectedImpact,
    FootWrenchLimit,
    HeldContactRows,
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
    jump_model_names,
)

from ..model.friction_pyramid import FrictionRows
from ..model.capture import floor_support_polygon
from ..model.humanoid_stance import stance_posture
from ..model.max_speed import Setting
from ..model.robot import RobotModel
from ..model.validation import BadInputError
from ..qp import ImpactAwareController
from .controller_config import ControllerConfig, TaskConfig, task_of


def build_controller(config: ControllerConfig, robot: RobotModel | None = None, q_start=None) -> ImpactAwareController:
    """The controller described by ``config`` (a fresh model of the configuration's robot and
    tool when ``robot`` is None; a given model of another arm takes the arm's configuration, a
    model that does not share the configuration robot's kind of base is bad input). A robot standing on held contacts gets their rows
    (``HeldContactRows``) and, with ``impact.capture_region``, the capture region of its support
    polygon at ``q_start`` (default: the posture of its description's default stance); with
    ``impact.foot_wrench``, the feet's rows at the impact (``FootWrenchLimit``, the feet as at
    ``q_start``, the closed form's equivalent contact duration); with ``impact.friction`` > 0, the
    same rows for every vertex of the friction pyramid (``EdgeCaptureRegionLimit``,
    ``EdgeFootWrenchLimit``)."""
    if not isinstance(config, ControllerConfig):
        raise BadInputError(f"build_controller needs a ControllerConfig, got a {type(config).__name__}")
    if robot is None:
        robot = config.choice.model()
    elif not isinstance(robot, RobotModel):
        raise BadInputError(f"build_controller's robot must be a RobotModel, got a {type(robot).__name__}")
    elif robot.floating != config.choice.robot.floating:  # an arm's tasks and rows would not hold a standing robot
        kinds = {True: "a floating-base robot's", False: "a fixed-base arm's"}
        raise BadInputError(
            f"the configuration is {kinds[config.choice.robot.floating]} ({config.choice.robot.name}) and the model "
            f"{kinds[robot.floating]} ({robot.description.name}): give a model of the configuration's robot, or none"
        )
    surface = config.surface.surface()
    limits, impact = config.limits, config.impact
    held_contacts = len(robot.description.held_contacts)

    tasks = [task_of(task, surface.normal, robot.description, robot.nv) for task in config.tasks]

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
    if held_contacts:
        constraints.append(HeldContactRows(6 * held_contacts))

    def impact_model(name: str, friction: FrictionRows) -> ExpectedImpact:
        rule = ActivationRule(impact.lookahead_distance, impact.lookahead_time, impact.release_speed, impact.always_active)
        return ExpectedImpact(surface, name, impact.restitution, rule, held_contacts > 0, friction)

    models = [impact_model(name, impact.friction_setting()) for name in jump_model_names(impact.jump_model)] if impact.jump_model else []
    polygon = support(robot, q_start) if held_contacts and impact.capture_region and models else None
    feet_start = start_posture(robot, q_start) if held_contacts and impact.foot_wrench and models else None
    edges = impact.friction_setting().count > 0  # every vertex's capture and feet rows
    capture_rows, feet_rows = (EdgeCaptureRegionLimit, EdgeFootWrenchLimit) if edges else (CaptureRegionLimit, FootWrenchLimit)
    for model in models:
        if impact.post_impact_velocity:
            constraints.append(PostImpactVelocityLimit(model, dq_max))
        if impact.impulsive_torque:
            constraints.append(ImpulsiveTorqueLimit(model, tau_max, dq_max, impact.impact_duration))
        if polygon is not None:
            constraints.append(capture_rows(model, polygon))
        if feet_start is not None:
            constraints.append(feet_rows(model, robot, feet_start, Setting().duration(robot.description)))
    prediction = models[0] if models else impact_model(impact.prediction_model, FrictionRows())
    return ImpactAwareController(
        robot, tasks, constraints, config.dt, config.solver, prediction,
        joint_limits=(ddq_max, dddq_max),
    )


def start_posture(robot: RobotModel, q_start=None):
    """``q_start``, or the posture of the robot's default stance when it is None."""
    if q_start is None:
        description = robot.description
        return stance_posture(robot, description.stances[description.default_posture])
    return q_start


def support(robot: RobotModel, q_start=None):
    """The support polygon of the robot's held contacts at ``q_start`` (default: its default
    stance) on the floor: the soles' hull, each corner of a raised sole projected from the CoM
    (``capture.floor_support_polygon``)."""
    q = start_posture(robot, q_start)
    return floor_support_polygon(robot, q, robot.terms(q).com)


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
    kept = [t for t in config.tasks if t.type != "contact_approach" and not (t.type == "frame" and t.params.get("frame") is None)]
    return replace(config, tasks=[offset_task, *kept], impact=impact)
