"""The impact-aware QP controller (``qp``, ``config``) above its ground (``model``: robot,
postures, jump predictors, maximum speed, input validation) and the measured-data layer beside the
ground (``measured``: dataset format, reader, validator, impact extraction)."""

from .config import ControllerConfig, build_controller
from .qp import Command, ImpactAwareController

__all__ = ["ImpactAwareController", "Command", "ControllerConfig", "build_controller"]
