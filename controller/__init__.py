"""The controller: the ground (``model``: robot, postures, jump maps, maximum speed, input
validation), the measured data beside it (``measured``: dataset format, reader, validator, impact
extraction), the impact-aware QP (``qp``) and its configuration (``config``) above them, and the
robot runtime on top (``runtime``: interface, 1 kHz loop, session, backends).

The first names are exported lazily (PEP 562), so that importing the ground or the measured data
(``impactqp.controller.model.robot``), which runs this file first, never loads the QP, its numba
kernels, a task or a constraint.
"""

from impactqp.lazy_exports import lazy_exports

_EXPORTS = {
    "ImpactAwareController": "impactqp.controller.qp",
    "Command": "impactqp.controller.qp",
    "ControllerConfig": "impactqp.controller.config",
    "build_controller": "impactqp.controller.config",
}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
