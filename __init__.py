"""impactqp: impact-aware task-space QP control of a Franka Panda.

The package predicts the joint-velocity jump of an impact with the composite-rigid-body method of
Wang, Dehio and Kheddar (RA-L 2022), beside the classical and generalized-momentum predictions
(``docs/predictors.md``), embeds it in a task-space QP as linear joint-velocity-limit constraints
(``docs/qp-constraints.md``), and exercises both on a MuJoCo Panda (``docs/simulation.md``).

The names a user needs first are exported here, lazily (PEP 562): ``import impactqp`` loads none
of them, and importing one module (say ``impactqp.controller.model.robot``) loads only what that
module imports, never the QP or MuJoCo. The layers of the package are listed in the README.
"""

from importlib import import_module, metadata

try:
    __version__ = metadata.version("impactqp")
except metadata.PackageNotFoundError:  # pragma: no cover - running from a tree that was never installed
    __version__ = "0+unknown"

_EXPORTS = {
    "PandaModel": "impactqp.controller.model.robot",
    "Surface": "impactqp.controller.model.postures",
    "DEFAULT_WALL": "impactqp.controller.model.postures",
    "POSTURES": "impactqp.controller.model.postures",
    "JumpModel": "impactqp.controller.model.jump",
    "JUMP_MODELS": "impactqp.controller.model.jump",
    "jump_model": "impactqp.controller.model.jump",
    "ImpactAwareController": "impactqp.controller",
    "Command": "impactqp.controller",
    "ControllerConfig": "impactqp.controller",
    "build_controller": "impactqp.controller",
}

__all__ = [*_EXPORTS, "__version__"]


def __getattr__(name: str):
    """The exported name ``name``, imported from its module on first use (PEP 562)."""
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
