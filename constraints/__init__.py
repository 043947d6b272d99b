"""Constraints of the impact-aware QP, rows in acceleration units (see ``constraints.constraint``):
the arm's, and the standing G1's (feet, impact rows of the floating base, capture region)."""

from .acceleration_limit import AccelerationLimit
from .capture_constraint import CaptureRegionLimit
from .constraint import Constraint, ConstraintRows, ControlCycle
from .floating_impact import FloatingExpectedImpact
from .floating_post_impact import FloatingPostImpactVelocityLimit
from .foot_contact import FootContact
from .impact_model import JUMP_MODEL_CHOICES, ExpectedImpact, jump_model_names
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
    "JUMP_MODEL_CHOICES",
    "jump_model_names",
    "PostImpactVelocityLimit",
    "ImpulsiveTorqueLimit",
    "FootContact",
    "FloatingExpectedImpact",
    "FloatingPostImpactVelocityLimit",
    "CaptureRegionLimit",
]
