"""The controller: the ground (``model``: robot, postures, jump maps, maximum speed, input
validation), the measured data beside it (``measured``: dataset format, reader, validator, impact
extraction), the impact-aware QP (``qp``) and its configuration (``config``) above them, and the
robot runtime on top (``runtime``: interface, 1 kHz loop, session, backends).

The first names are exported lazily (PEP 562), so that importing the ground or the measured data
(``impactqp.controller.model.robot``), which runs this file first, never loads the QP, its numba
kernels, a task or a constraint.
"""

from importlib import import_module

_EXPORTS = {
    "ImpactAwareController": "impactqp.controller.qp",
    "Command": "impactqp.controller.qp",
    "ControllerConfig": "impactqp.controller.config",
    "build_controller": "impactqp.controller.config",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    """The exported name ``name``, imported from its module on first use (PEP 562)."""
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
