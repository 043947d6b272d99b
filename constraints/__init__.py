"""Constraints of the impact-aware QP, rows in acceleration units (see ``constraints.constraint``):
every robot's (limits, expected impact and its rows), and those of a robot standing on held
contacts (the held contacts' rows, the capture region, the feet's wrenches at the impact)."""

from .acceleration_limit import AccelerationLimit
from .capture_constraint import CaptureRegionLimit, EdgeCaptureRegionLimit
from .constraint import Constraint, ConstraintRows, ControlCycle
from .foot_wrench import EdgeFootWrenchLimit, FootWrenchLimit
from .held_contact import HeldContactRows
from .impact_model import JUMP_MODEL_CHOICES, ActivationRule, ExpectedImpact, jump_model_names
from .impulsive_torque import ImpulsiveTorqueLimit
from .position_limit import PositionLimit
from .post_impact_velocity import PostImpactVelocityLimit
from .torque_limit import TorqueLimit
from .velocity_limit import VelocityLimit

__all__ = [
    "Constraint",
    "ConstraintRows",
    "ControlCycle",
    "AccelerationLimit",
    "PositionLimit",
    "VelocityLimit",
    "TorqueLimit",
    "ExpectedImpact",
    "ActivationRule",
    "JUMP_MODEL_CHOICES",
    "jump_model_names",
    "PostImpactVelocityLimit",
    "ImpulsiveTorqueLimit",
    "HeldContactRows",
    "CaptureRegionLimit",
    "EdgeCaptureRegionLimit",
    "FootWrenchLimit",
    "EdgeFootWrenchLimit",
]
