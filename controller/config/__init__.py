"""Controller configuration: ``ControllerConfig`` (a dataclass, loadable from a TOML or YAML file,
``controller_config``) and the controller it describes (``build_controller``, ``build``)."""

from .build import build_controller, post_impact_config
from .controller_config import (
    ApproachOptions,
    ControllerConfig,
    ImpactConfig,
    LimitsConfig,
    PostImpactConfig,
    SurfaceConfig,
    TaskConfig,
)

__all__ = [
    "ApproachOptions", "ControllerConfig", "ImpactConfig", "LimitsConfig", "PostImpactConfig", "SurfaceConfig",
    "TaskConfig", "build_controller", "post_impact_config",
]
