"""The controller: the ground (``model``: robot, postures, jump maps, maximum speed, input
validation), the measured data beside it (``measured``: dataset format, reader, validator, impact
extraction), the impact-aware QP (``qp``) and its configuration (``config``) above them, and the
robot runtime on top (``runtime``: interface, 1 kHz loop, session, backends).

The names a user composes (the controllers, their configuration, the robot model and the impact
session) are exported lazily (PEP 562), so that importing the ground or the measured data
(``impactqp.controller.model.robot``), which runs this file first, never loads the QP, its numba
kernels, a task or a constraint.
"""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_CONFIG = "impactqp.controller.config"
_EXPORTS = {
    "RobotModel": "impactqp.controller.model",
    "RobotChoice": "impactqp.controller.model",
    "BadInputError": "impactqp.controller.model",
    "ImpactAwareController": "impactqp.controller.qp",
    "Command": "impactqp.controller.qp",
    "Status": "impactqp.controller.qp",
    "ControllerConfig": _CONFIG,
    "TaskConfig": _CONFIG,
    "LimitsConfig": _CONFIG,
    "ImpactConfig": _CONFIG,
    "PostImpactConfig": _CONFIG,
    "SurfaceConfig": _CONFIG,
    "build_controller": _CONFIG,
    "post_impact_config": _CONFIG,
    "RobotConfig": "impactqp.controller.robot_config",
    "ImpactSession": "impactqp.controller.runtime",
}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
