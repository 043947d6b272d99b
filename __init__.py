"""impactqp: impact-aware task-space QP control of a Franka Panda.

The package predicts the joint-velocity jump of an impact with the composite-rigid-body method of
Wang, Dehio and Kheddar (RA-L 2022), beside the classical and generalized-momentum predictions
(``docs/predictors.md``), embeds it in a task-space QP as linear joint-velocity-limit constraints
(``docs/qp-constraints.md``), and exercises both on a MuJoCo Panda (``docs/simulation.md``).

The names a user needs first are exported here; the layers of the package are listed in the README.
"""

from importlib import metadata

from impactqp.controller import Command, ControllerConfig, ImpactAwareController, build_controller
from impactqp.controller.model.jump import JUMP_MODELS, JumpModel, jump_model
from impactqp.controller.model.postures import DEFAULT_WALL, POSTURES, Surface
from impactqp.controller.model.robot import PandaModel

try:
    __version__ = metadata.version("impactqp")
except metadata.PackageNotFoundError:  # pragma: no cover - running from a tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "PandaModel",
    "Surface",
    "DEFAULT_WALL",
    "POSTURES",
    "JumpModel",
    "JUMP_MODELS",
    "jump_model",
    "ImpactAwareController",
    "Command",
    "ControllerConfig",
    "build_controller",
    "__version__",
]
