"""``impactqp run``: one run of the impact session on a backend, with its report and its log.

``run(request)`` builds the controller configuration (``--config`` or the default approach to
the posture's wall at ``--speed``), the backend, the session and the loop, runs it, writes the
log in the dataset format (``controller.measured.dataset``, one trial per run, with ``dq_cmd``
and, in simulation, the contact force) so that ``impactqp diagnose`` reads it, and returns the
report of ``impactqp run --json``. Bad input raises ``BadInputError``.
"""

from __future__ import annotations

import signal
import threading
from dataclasses import dataclass

import numpy as np

from impactqp.controller.command_filter import CommandFilter
from impactqp.controller.config import ControllerConfig
from impactqp.controller.measured.dataset import MODELLED_TOOL, DatasetHeader
from impactqp.controller.measured.impact import DEFAULT_FORCE_THRESHOLD
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.robot import NQ, PandaModel
from impactqp.controller.model.validation import BadInputError, approach_speed, number_in_range

from .interface import RobotInterface
from .loop import ControlLoop, LoopResult
from .run_log import RunLog
from .session import ImpactSession

BACKENDS = ("sim", "franka", "replay")
SIM_START_DISTANCE = 0.05
MAX_DURATION = 60.0
"""s: one impact session (approach, impact, post-impact phase) lasts seconds; a minute bounds it."""


@dataclass(frozen=True)
class RunRequest:
    """The options of ``impactqp run`` (``docs/robot-loop.md``)."""

    backend: str = "sim"
    robot_ip: str | None = None
    config_file: str | None = None
    plant_file: str | None = None
    posture: str = "elbow_up"
    speed: float = 0.15
    duration: float = 1.0
    log_dir: str | None = None
    dataset: str | None = None
    trial: str | None = None
    paced: bool = True
    deadline: float | None = None  # None: the period, or no deadline offline (replay, unpaced sim)
    max_overruns: int = 5


def controller_config(request: RunRequest, surface=None) -> ControllerConfig:
    if request.config_file is not None:
        try:
            return ControllerConfig.from_file(request.config_file)
        except BadInputError as error:
            raise BadInputError(f"--config {error}") from None
    if surface is None:
        surface = POSTURES[request.posture].surface
    return ControllerConfig.approach(surface, request.speed, posture_weight=0.0)


def check_request(request: RunRequest) -> None:
    if request.backend not in BACKENDS:
        raise BadInputError(f"--backend {request.backend!r}: choose from {', '.join(BACKENDS)}")
    if request.posture not in POSTURES:
        raise BadInputError(f"--posture {request.posture!r} is unknown; known: {', '.join(POSTURES)}")
    approach_speed(request.speed, "--speed")
    number_in_range(request.duration, 0.0, MAX_DURATION, "--duration", "s", low_open=True)
    if request.backend == "franka" and not request.robot_ip:
        raise BadInputError("--backend franka needs --robot-ip IP")
    if request.backend == "replay" and not request.dataset:
        raise BadInputError("--backend replay needs --dataset DIR (and optionally --trial ID)")


def build_backend(request: RunRequest, model: PandaModel) -> tuple[RobotInterface, ControllerConfig, float]:
    """(backend, controller configuration, duration) of the request."""
    if request.backend == "franka":
        from .franka_backend import FrankaRobot

        config = controller_config(request)
        return FrankaRobot.connect(request.robot_ip), config, request.duration
    if request.backend == "replay":
        from .replay_backend import ReplayRobot, load_trial

        trial, header = load_trial(request.dataset, request.trial)
        speed = trial.entry.reference_normal_speed
        config = controller_config(RunRequest(**{**request.__dict__, "speed": speed}), header.surface)
        return ReplayRobot(trial, header.control_period), config, len(trial.log) * header.control_period
    from impactqp.sim.plant import PlantParameterError, PlantParameters
    from impactqp.sim.runner import UnreachableStartError, approach_start
    from impactqp.sim.scene import build_scene

    config = controller_config(request)
    try:
        plant = None if request.plant_file is None else PlantParameters.from_json(request.plant_file)
    except PlantParameterError as error:
        raise BadInputError(f"--plant: {error}") from None
    surface = config.surface.surface()
    try:
        q0 = approach_start(model, POSTURES[request.posture].q, surface, SIM_START_DISTANCE)
    except UnreachableStartError as error:
        raise BadInputError(str(error)) from None
    from .sim_backend import SimRobot

    robot = SimRobot(build_scene(surface, plant), q0, np.zeros(NQ), config.dt, paced=request.paced)
    return robot, config, request.duration


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def run(request: RunRequest) -> tuple[dict, LoopResult]:
    """Run the request; (report, result). Ctrl-C, SIGTERM or SIGHUP brakes to a stop and keeps the log
    (``result.interrupted``). The log directory is checked before the robot moves."""
    check_request(request)
    model = PandaModel()
    robot, config, duration = build_backend(request, model)
    run_log = RunLog(request.log_dir, log_header(config)) if request.log_dir else None
    session = ImpactSession(config, model)
    deadline = request.deadline
    if deadline is None and (request.backend == "replay" or not request.paced):
        deadline = float("inf")  # offline: the plant waits for the controller
    loop = ControlLoop(
        robot, session, CommandFilter.for_robot(model, config.dt), deadline=deadline, max_overruns=request.max_overruns
    )
    if threading.current_thread() is threading.main_thread():
        previous = {sig: signal.signal(sig, lambda *_: loop.request_stop()) for sig in STOP_SIGNALS}
        try:
            result = loop.run(duration)
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
    else:  # signal handlers can only be set in the main thread
        result = loop.run(duration)
    log_path = write_log(run_log, request, config, result) if run_log is not None else None
    return report(result, config, log_path), result


def contact_start(result: LoopResult) -> float | None:
    """First time the logged contact force exceeds the offline rule's threshold (None without)."""
    log = result.log
    if not log.has_force:
        return None
    above = np.linalg.norm(log.force, axis=1) > DEFAULT_FORCE_THRESHOLD
    return float(log.force_t[np.argmax(above)]) if above.any() else None


def report(result: LoopResult, config: ControllerConfig, log_path: str | None) -> dict:
    """The ``impactqp run --json`` object."""
    session = result.session
    detector = session.detector
    t_contact = contact_start(result)
    latency = None
    if detector.detected and t_contact is not None:
        latency = (detector.t_detect - t_contact) * 1e3
    return {
        "cycles": result.cycles,
        "overruns": result.overruns,
        "cycle_us": result.cycle_us,
        "watchdog_trips": result.watchdog_trips,
        "watchdog_reason": result.watchdog_reason,
        "impact": {
            "detected": detector.detected,
            "time": detector.t_detect,
            "detection_latency_ms": latency,
            "contact_speed": session.contact_speed(),
            "residual": session.residual_source,
        },
        "phase": result.phase,
        "log": log_path,
    }


def log_header(config: ControllerConfig) -> DatasetHeader:
    return DatasetHeader(
        tool=MODELLED_TOOL,
        surface=config.surface.surface(),
        control_period=config.dt,
    )


def after(log: TrialLog, t_start: float) -> TrialLog:
    """The samples of a log without force from ``t_start`` on."""
    k = int(np.searchsorted(log.t, t_start))
    return TrialLog(log.t[k:], log.q[k:], log.dq[k:], log.tau[k:], log.dq_cmd[k:])


def write_log(run_log: RunLog, request: RunRequest, config: ControllerConfig, result: LoopResult) -> str:
    """Add the run as one trial to its dataset; the trial file's path.

    A log without a force measurement (a robot's) is written from the end of the detector's
    contact-free reference window on: the offline torque rule (``controller.measured.impact``)
    reads a trial that starts in the approach, and would take the start-up of a velocity-servoed
    arm from rest (the joint torque following the commanded acceleration) for an impact."""
    speed = next(
        (float(t.params.get("speed", 0.0)) for t in config.tasks if t.type == "contact_approach"), request.speed
    )
    log = result.log
    t_reference = result.session.detector.t_calibrated
    if not log.has_force and t_reference is not None:
        log = after(log, t_reference)
    return run_log.add(
        log,
        speed,
        posture=request.posture if request.backend == "sim" else None,
        impact_time=contact_start(result) if log.has_force else result.session.detector.t_detect,
    )
