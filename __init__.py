"""impactqp: impact-aware task-space QP control of Franka arms (Panda, FR3) and a standing humanoid.

The package predicts the joint-velocity jump of an impact with the composite-rigid-body method of
Wang, Dehio and Kheddar (RA-L 2022), beside the classical and generalized-momentum predictions
(``docs/predictors.md``), embeds it in a task-space QP as linear joint-velocity-limit constraints
(``docs/qp-constraints.md``), and exercises both on a MuJoCo Panda (``docs/simulation.md``).

The names a user needs first are exported here, lazily (PEP 562): ``import impactqp`` loads none
of them, and importing one module (say ``impactqp.controller.model.robot``) loads only what that
module imports, never the QP or MuJoCo. The layers of the package are listed in the README.
"""

from importlib import metadata

from impactqp.lazy_exports import lazy_exports

try:
    __version__ = metadata.version("impactqp")
except metadata.PackageNotFoundError:  # pragma: no cover - running from a tree that was never installed
    __version__ = "0+unknown"

_EXPORTS = {
    "PandaModel": "impactqp.controller.model.robot",
    "RobotModel": "impactqp.controller.model.robot",
    "Surface": "impactqp.controller.model.postures",
    "DEFAULT_WALL": "impactqp.controller.model.postures",
    "JumpModel": "impactqp.controller.model.jump",
    "JUMP_MODELS": "impactqp.controller.model.jump",
    "jump_model": "impactqp.controller.model.jump",
    "ImpactAwareController": "impactqp.controller",
    "Command": "impactqp.controller",
    "ControllerConfig": "impactqp.controller",
    "build_controller": "impactqp.controller",
}

__all__ = [*_EXPORTS, "__version__"]


__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
