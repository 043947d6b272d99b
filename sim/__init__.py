"""The simulation: the MuJoCo scene of a robot, its tool and a wall (``scene``), the plant's
parameters (``plant``), joint servo (``servo``) and sensors (``sensor``), the one 1 kHz closed-loop
trial of every robot (``trial_loop``), the one trial runner (``runner``), its command sources
(``trial_sources``) and its result (``trial_result``), the simulated robot behind the runtime's interface (``sim_backend``),
simulated datasets (``generation``), the candidate causes of a sim-to-real gap (``causes``) and
their diagnosis (``diagnosis``), the standing G1's feet (``humanoid_feet``; its scene in
``scene``, its trial in ``runner``), and the render-only model of a scene with the robot's
meshes (``render_scene``).

Its names are exported lazily (PEP 562): importing one module loads only its own imports.
"""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    "Scene": "scene",
    "build_scene": "scene",
    "PlantParameters": "plant",
    "PlantParameterError": "plant",
    "apply_sensor": "sensor",
    "TrialSpec": "runner",
    "run_trial": "runner",
    "run_approach": "runner",
    "VelocityCommand": "trial_loop",
    "run_impact": "runner",
    "TrialStart": "trial_sources",
    "CartesianApproachCommand": "trial_sources",
    "CommandReplay": "trial_sources",
    "SimulationUnstableError": "runner",
    "ComputedTorqueServo": "servo",
    "SimRobot": "sim_backend",
    "DatasetRequest": "generation",
    "generate_dataset": "generation",
    "Cause": "causes",
    "default_causes": "causes",
    "HumanoidScene": "humanoid_scene",
    "build_humanoid_scene": "humanoid_scene",
    "TrialResult": "trial_result",
    "HeldContactResult": "trial_result",
    "run_impact_trial": "runner",
    "QpCommand": "trial_sources",
    "ScriptedCommand": "trial_sources",
    "ProcessPool": "process_pool",
    "RenderScene": "render_scene",
    "arm_render_scene": "render_scene",
    "humanoid_render_scene": "render_scene",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
