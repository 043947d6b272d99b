"""The standing G1's whole-body QP for one hand impact, assembled from its tasks and constraints
(docs/whole-body-qp.md): ``WholeBodySetup`` and ``build_whole_body_controller``.

Tasks (weighted least squares in dv): the hand's ``ContactApproachTask`` towards the surface,
the ``CentreOfMassTask`` holding the CoM, the torso's orientation (``FrameTask`` on the torso
frame, orientation rows only), a ``PostureTask`` on the joints and a ``DampingTask`` on the
nv velocities (strict convexity). Constraints: the joints' acceleration and jerk limits, their
position limits (braking horizon) and velocity limits, the feet (``HeldContactRows``, equality
rows), the predicted post-impact joint velocities (``PostImpactVelocityLimit``) and the
predicted post-impact CoM velocity inside the stance's capture region (``CaptureRegionLimit``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.constraints import (
    AccelerationLimit,
    CaptureRegionLimit,
    ExpectedImpact,
    HeldContactRows,
    PositionLimit,
    PostImpactVelocityLimit,
    VelocityLimit,
)
from impactqp.controller.model.humanoid_stance import support_polygon
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.whole_body_terms import WholeBodyModel
from impactqp.tasks import ContactApproachTask, DampingTask, FrameTask, PostureTask
from impactqp.tasks import CentreOfMassTask

from .controller import ImpactAwareController


@dataclass(frozen=True)
class WholeBodySetup:
    """The choices of one whole-body controller: the surface the hand approaches at ``speed``
    (m/s), the jump predictor (crb, gm or classical) and restitution of the impact rows, whether
    they are always on (else the activation rule decides), the control period and solver, and
    the task weights."""

    surface: Surface
    speed: float = 0.3
    method: str = "crb"
    restitution: float = 0.0
    always_active: bool = False
    dt: float = 0.001
    solver: str = "daqp"
    com_weight: float = 10.0
    torso_weight: float = 10.0
    posture_weight: float = 1e-4


def build_whole_body_controller(robot: WholeBodyModel, q_stance: np.ndarray, setup: WholeBodySetup) -> ImpactAwareController:
    """The controller of ``setup`` for the robot standing at ``q_stance`` (its feet's support
    polygon bounds the capture region)."""
    impact = ExpectedImpact(
        setup.surface, setup.method, setup.restitution, always_active=setup.always_active, held_contacts=True
    )
    tasks = [
        ContactApproachTask(setup.surface.normal, setup.speed),
        CentreOfMassTask(weight=(setup.com_weight,) * 3),
        FrameTask(position_weight=0.0, orientation_weight=setup.torso_weight, frame="torso"),
        PostureTask(weight=setup.posture_weight, joints=robot.joints),
        DampingTask(variables=robot.nv),
    ]
    constraints = [
        AccelerationLimit(),
        PositionLimit(robot.q_min, robot.q_max, robot.ddq_max),
        VelocityLimit(robot.dq_max),
        HeldContactRows(6 * len(robot.base.foot_frame_ids)),
        PostImpactVelocityLimit(impact, robot.dq_max),
        CaptureRegionLimit(impact, support_polygon(robot.base, q_stance)),
    ]
    return ImpactAwareController(robot, tasks, constraints, setup.dt, setup.solver, impact)
