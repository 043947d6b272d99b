"""The robot runtime (``docs/robot-loop.md``): the robot interface, the 1 kHz loop runner with its
watchdog and command filter, the impact session (controller, online impact detection and
post-impact phase), the run log, the move to the start posture, and the backends of what this
layer can reach (``franka``: an FR3 through pylibfranka; ``panda``: a Panda through
panda-python's libfranka 0.9; both imported only when chosen, their shared settings, model check
and statistics in ``libfranka_robot``; ``replay``: a measured trial). The MuJoCo backend sits
with the simulation (``sim.sim_backend``). It imports no MuJoCo.

Its names are exported lazily (PEP 562): importing the loop or the interface loads neither the
QP nor a backend's library (pylibfranka, panda-python, ruckig)."""

from impactqp.lazy_exports import lazy_exports as _lazy_exports

_EXPORTS = {
    "ImpactSession": "session",
    "RobotInterface": "interface",
    "RobotState": "interface",
    "ControlLoop": "loop",
    "LoopResult": "loop",
    "Watchdog": "loop",
    "CommandFilter": "command_filter",
    "ImpactDetector": "impact_detector",
    "MomentumObserver": "impact_detector",
    "RunLog": "run_log",
    "StartMove": "start_move",
    "FrankaRobot": "franka_backend",
    "PandaRobot": "panda_backend",
    "ReplayRobot": "replay_backend",
}
_EXPORTS = {name: f"{__name__}.{module}" for name, module in _EXPORTS.items()}

__all__ = list(_EXPORTS)


__getattr__, __dir__ = _lazy_exports(globals(), _EXPORTS)
