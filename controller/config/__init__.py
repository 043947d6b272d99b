"""Controller configuration: ``ControllerConfig`` (a dataclass, loadable from a TOML or YAML file,
``controller_config``), the controller it describes (``build_controller``, ``build``) and a
standing robot's balance after the impact (``balance_after_impact``, ``post_impact_balance``)."""

from .build import build_controller, post_impact_config
from .post_impact_balance import balance_after_impact
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
    "TaskConfig", "balance_after_impact", "build_controller", "post_impact_config",
]
