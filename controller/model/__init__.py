"""The ground of the package: the robot descriptions and model, postures and surfaces, the jump predictors, the batch
API, the closed-form maximum speed and input validation. It imports nothing above it.

Its names are exported lazily (PEP 562): importing one module of the ground (``validation``,
say) loads that module's imports, not Pinocchio's model or the numba kernels of the others.
"""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    # the robot and the tool
    "RobotModel": "robot",
    "PandaModel": "robot",
    "ModelTerms": "model_terms",
    "FrameState": "model_terms",
    "RobotDescription": "robot_description",
    "ROBOTS": "robot_description",
    "PANDA": "robot_description",
    "load_robot_description": "robot_description",
    "ToolDescription": "tool_description",
    "TOOLS": "tool_description",
    "Sphere": "tool_description",
    "Pad": "tool_description",
    "read_tool_file": "tool_description",
    "tool_from_dict": "tool_description",
    "RobotChoice": "choice",
    "DEFAULT_CHOICE": "choice",
    # surfaces and postures
    "Surface": "postures",
    "ImpactPosture": "postures",
    "DEFAULT_WALL": "postures",
    "tool_posture": "tool_postures",
    "ContactPosture": "inverse_kinematics",
    "contact_posture": "inverse_kinematics",
    # the jump predictors
    "JumpModel": "jump",
    "JumpPrediction": "jump",
    "JumpMaps": "jump",
    "JumpMatrices": "jump",
    "JUMP_MODELS": "jump",
    "jump_model": "jump",
    "predict": "jump",
    "prediction_error": "jump_error",
    "average_prediction_error": "jump_error",
    "ImpactQuery": "prediction",
    "predict_all": "prediction",
    "BatchKinematics": "batch",
    "BatchTerms": "batch",
    "predict_batch": "batch",
    "CrbPredictor": "crb_prediction",
    # the robust friction rows
    "FrictionRows": "friction_pyramid",
    # the highest feasible contact speed
    "MaxSpeed": "max_speed",
    "MaxSpeeds": "max_speed",
    "closed_form_max_speed": "max_speed",
    "closed_form_max_speeds": "max_speed",
    "frictional_max_speed": "friction_max_speed",
    # the standing humanoid
    "Stance": "robot_description",
    "STANCES": "humanoid_stance",
    "stance_posture": "humanoid_stance",
    "CaptureRegion": "capture",
    "capture_region": "capture",
    # input validation
    "BadInputError": "validation",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
