"""impactqp: impact-aware task-space QP control of any robot described in one file: Franka arms (Panda, FR3), a UR5 and a standing humanoid (G1).

The package predicts the joint-velocity jump of an impact with the composite-rigid-body method of
Wang, Dehio and Kheddar (RA-L 2022), beside the classical and generalized-momentum predictions
(``docs/predictors.md``), embeds it in a task-space QP as linear joint-velocity-limit constraints
(``docs/qp-constraints.md``), and exercises both on a MuJoCo Panda (``docs/simulation.md``).

The names a robotics engineer composes are exported here (``__all__``): the robot model and its
descriptions, the jump predictors, the controller with its configuration, tasks and constraints,
the impact session of a robot loop, and the simulated scene and trial. They are exported lazily
(PEP 562): ``import impactqp`` loads none of them (nor NumPy, Pinocchio or MuJoCo), and importing
one module (say ``impactqp.controller.model.robot``) loads only what that module imports, never
the QP or MuJoCo. The layers of the package are listed in docs/layout.md; each subpackage exports the
names of its own layer.
"""

import os as _os


def _numba_cache_dir() -> None:
    """Point numba's cache of compiled kernels (``cache=True``) at the temporary directory when
    neither of its own places can be written: beside the sources (``__pycache__``) and the user's
    cache directory (``$XDG_CACHE_HOME`` or ``~/.cache``, then ``numba``), as for a read-only
    install run by a user without a home, where numba refuses to load a kernel at all. A
    ``NUMBA_CACHE_DIR`` already set is kept."""
    import tempfile

    if "NUMBA_CACHE_DIR" in _os.environ:
        return
    user_cache = _os.environ.get("XDG_CACHE_HOME") or _os.path.expanduser("~/.cache")
    for place in (_os.path.join(_os.path.dirname(__file__), "__pycache__"), _os.path.join(user_cache, "numba")):
        try:
            _os.makedirs(place, exist_ok=True)
            tempfile.TemporaryFile(dir=place).close()
            return
        except OSError:
            continue
    _os.environ["NUMBA_CACHE_DIR"] = _os.path.join(tempfile.gettempdir(), f"impactqp-numba-{_os.getuid()}")


_numba_cache_dir()

from impactqp.lazy_exports import lazy_exports as _lazy_exports  # noqa: E402

_MODEL = "impactqp.controller.model"
_QP = "impactqp.controller.qp"
_EXPORTS = {
    # the robot model, its descriptions and its surfaces (the ground)
    "BadInputError": f"{_MODEL}.validation",
    "RobotModel": f"{_MODEL}.robot",
    "PandaModel": f"{_MODEL}.robot",
    "ModelTerms": f"{_MODEL}.model_terms",
    "RobotChoice": f"{_MODEL}.choice",
    "RobotDescription": f"{_MODEL}.robot_description",
    "robot_description": f"{_MODEL}.robot_description",
    "ToolDescription": f"{_MODEL}.tool_description",
    "tool_description": f"{_MODEL}.tool_description",
    "Surface": f"{_MODEL}.postures",
    "DEFAULT_WALL": f"{_MODEL}.postures",
    "ROBOTS": f"{_MODEL}.robot_description",
    # the jump predictors, their results and the highest feasible contact speed
    "JumpModel": f"{_MODEL}.jump",
    "JumpPrediction": f"{_MODEL}.jump",
    "JUMP_MODELS": f"{_MODEL}.jump",
    "jump_model": f"{_MODEL}.jump",
    "prediction_error": f"{_MODEL}.jump_error",
    "average_prediction_error": f"{_MODEL}.jump_error",
    "BatchKinematics": f"{_MODEL}.batch",
    "predict_batch": f"{_MODEL}.batch",
    "MaxSpeed": f"{_MODEL}.max_speed",
    "closed_form_max_speed": f"{_MODEL}.max_speed",
    # the controller and its configuration
    "ImpactAwareController": _QP,
    "Command": _QP,
    "Status": _QP,
    "ControllerConfig": "impactqp.controller.config",
    "build_controller": "impactqp.controller.config",
    # tasks and constraints
    "Task": "impactqp.tasks",
    "FrameTask": "impactqp.tasks",
    "ContactApproachTask": "impactqp.tasks",
    "PostureTask": "impactqp.tasks",
    "DampingTask": "impactqp.tasks",
    "SurfaceOffsetTask": "impactqp.tasks",
    "CentreOfMassTask": "impactqp.tasks",
    "Constraint": "impactqp.constraints",
    "PositionLimit": "impactqp.constraints",
    "VelocityLimit": "impactqp.constraints",
    "AccelerationLimit": "impactqp.constraints",
    "TorqueLimit": "impactqp.constraints",
    "ExpectedImpact": "impactqp.constraints",
    "ActivationRule": "impactqp.constraints",
    "FrictionRows": "impactqp.controller.model",
    "PostImpactVelocityLimit": "impactqp.constraints",
    "ImpulsiveTorqueLimit": "impactqp.constraints",
    "HeldContactRows": "impactqp.constraints",
    "CaptureRegionLimit": "impactqp.constraints",
    # the robot loop
    "ImpactSession": "impactqp.controller.runtime",
    "RobotInterface": "impactqp.controller.runtime",
    "RobotState": "impactqp.controller.runtime",
    "ControlLoop": "impactqp.controller.runtime",
    # the simulation
    "Scene": "impactqp.sim",
    "build_scene": "impactqp.sim",
    "PlantParameters": "impactqp.sim",
    "TrialSpec": "impactqp.sim",
    "TrialRunner": "impactqp.scenarios",
    "TrialResult": "impactqp.sim",
}

__all__ = [*_EXPORTS, "__version__"]


_export, _exported = _lazy_exports(globals(), _EXPORTS)


def __getattr__(name: str):
    """An export, or ``__version__``: read from the installed metadata on first use (reading it
    costs tens of milliseconds, which the command line must not spend before its signal
    handlers are in)."""
    if name != "__version__":
        return _export(name)
    from importlib import metadata

    try:
        version = metadata.version("impactqp")
    except metadata.PackageNotFoundError:  # pragma: no cover - a tree that was never installed
        version = "0+unknown"
    globals()["__version__"] = version
    return version


def __dir__() -> list[str]:
    return sorted({*_exported(), "__version__"})
