"""``impactqp run``: one run of the impact session on a backend, with its report and its log.

``run(request)`` builds the controller configuration (``--config`` or the default approach to
the posture's wall at ``--speed``), the backend, the session and the loop, runs it, writes the
log in the dataset format (``controller.measured.dataset``, one trial per run, with ``dq_cmd``
and, in simulation, the contact force) so that ``impactqp diagnose`` reads it, and returns the
report of ``impactqp run --json``. Bad input raises ``BadInputError``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from impactqp.controller.config import ControllerConfig, TaskConfig
from impactqp.controller.measured.dataset import DatasetHeader
from impactqp.controller.measured.impact import DEFAULT_FORCE_THRESHOLD
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.inverse_kinematics import UnreachableStartError, approach_start
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError, approach_speed, number_in_range
from impactqp.controller.runtime.collision_thresholds import CollisionThresholds, impact_thresholds, predicted_peaks
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.runtime.franka_backend import FrankaRobot
from impactqp.controller.runtime.interface import RobotInterface
from impactqp.controller.runtime.loop import ControlLoop, LoopResult
from impactqp.controller.runtime.panda_backend import PandaRobot
from impactqp.controller.runtime.replay_backend import ReplayRobot, load_trial
from impactqp.controller.runtime.run_log import RunLog
from impactqp.controller.runtime.session import ImpactSession
from impactqp.controller.runtime.start_move import StartMove
from impactqp.scenarios.stop_signals import StopSignals
from impactqp.sim.plant import PlantParameterError, PlantParameters
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.postures import Surface
from impactqp.sim.runner import NORMAL as STANDING_NORMAL
from impactqp.sim.runner import SERVO_GAIN, SETTLE, SINK
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.scene import build_scene
from impactqp.sim.servo import StandingSupport
from impactqp.sim.sim_backend import SimRobot

BACKENDS = ("sim", "franka", "panda", "replay")
ROBOT_BACKENDS = ("franka", "panda")  # a real robot: connect, check the model, move to the start posture
BACKEND_ROBOTS = {"franka": "fr3", "panda": "panda"}
"""The robot each robot backend drives: pylibfranka (libfranka >= 0.10) serves the FR3 only,
libfranka 0.9 (panda-python) the Panda only (Franka's compatibility matrix)."""
SIM_START_DISTANCE = 0.05
IMPACT_LEAD = 0.15
"""s of a robot's log kept before the detected impact: more than every offline reading of the
pre-impact state needs (the diagnosis replays from 40 ms before the impact), and short enough to
leave out the approach's acceleration, whose torque transients the offline rule would take for
an impact on a log without force (``write_log``)."""
MAX_DURATION = 60.0
"""s: one impact session (approach, impact, post-impact phase) lasts seconds; a minute bounds it."""


@dataclass(frozen=True)
class RunRequest:
    """The options of ``impactqp run`` (``docs/robot-loop.md``); each field is named after its
    option.

    backend
        ``--backend``: ``sim`` (MuJoCo), ``franka`` (an FR3 through pylibfranka), ``panda`` (a
        Panda through panda-python's libfranka 0.9) or ``replay`` (a dataset trial played back).
    robot_ip
        ``--robot-ip``: the robot's address (franka and panda backends).
    realtime
        ``--realtime enforce|ignore``: True requires a real-time kernel for libfranka (franka and
        panda backends); False runs without one and keeps no deadline (a simulator of the robot
        that waits for the controller, such as franky-sim in lockstep: ``sim.franky_sim``).
    config_file
        ``--config``: a controller configuration file (.toml, .yaml); None: the default approach
        to ``posture``'s wall at ``speed``.
    plant_file
        ``--plant``: a JSON file of plant-parameter overrides (sim backend); None: nominal.
    posture
        ``--posture``: the named start posture (sim backend); None: the robot's default posture
        (its description's ``default_posture``).
    speed
        ``--speed``: approach speed (m/s) of the default configuration.
    duration
        ``--duration``: control time (s) before braking to a stop, in (0, ``MAX_DURATION``].
    log
        ``--log``: the dataset directory the run is added to as one trial; None: no log.
    dataset
        ``--dataset``: the dataset directory of the trial to replay (replay backend).
    trial
        ``--trial``: the id of the trial to replay; None: the first.
    unpaced
        ``--unpaced``: run the sim backend as fast as it goes, without wall-clock pacing.
    deadline
        Time (s) from a state read to its command after which a cycle counts as an overrun;
        None: the control period, and no deadline offline (replay, unpaced sim) or without a
        real-time kernel (``realtime`` False). No option.
    max_overruns
        Overruns in a row that trip the watchdog. No option.
    choice
        ``--robot`` and ``--tool``. A configuration file's ``robot``/``tool`` and a replayed
        dataset's manifest decide; a non-default choice that disagrees with them is bad input.
        The franka backend drives an ``fr3``, the panda backend a ``panda``.
    """

    backend: str = "sim"
    robot_ip: str | None = None
    realtime: bool = True
    config_file: str | None = None
    plant_file: str | None = None
    posture: str | None = None
    speed: float = 0.15
    duration: float = 1.0
    log: str | None = None
    dataset: str | None = None
    trial: str | None = None
    unpaced: bool = False
    deadline: float | None = None
    max_overruns: int = 5
    choice: RobotChoice = DEFAULT_CHOICE


def with_posture_target(config: ControllerConfig, q) -> ControllerConfig:
    """``config`` with ``q`` the target of every posture task that has none, so that the task
    holds the start posture for the whole session (without a target it would take the posture
    at each controller's reset, the impact's for the post-impact controller)."""
    tasks = [
        TaskConfig(t.type, {**t.params, "target": [float(x) for x in q]})
        if t.type == "posture" and t.params.get("target") is None else t
        for t in config.tasks
    ]
    return replace(config, tasks=tasks)


def controller_config(request: RunRequest, surface=None, decided: RobotChoice | None = None) -> ControllerConfig:
    """The configuration file's, or the default approach of ``request.choice``'s robot and tool
    to ``surface`` (the posture's wall by default). ``decided`` is the robot and tool the data
    impose (a replayed manifest's): the configuration must agree with it. On a robot a weak
    posture task keeps the wrist where the start move put it."""
    if request.config_file is not None:
        try:
            config = ControllerConfig.from_file(request.config_file)
        except BadInputError as error:
            raise BadInputError(f"--config {error}") from None
        if decided is not None:
            _agree(decided, "the dataset's manifest", config.choice, "the configuration's")
        elif not request.choice.is_default:
            _agree(config.choice, "the configuration", request.choice, "--robot/--tool")
        return config
    choice = request.choice if decided is None else decided
    if surface is None:
        surface = choice.posture(request.posture or choice.robot.default_posture).surface
    if choice.robot.floating:  # the robot's own preset (its balance tasks and weights)
        config = ControllerConfig.approach(surface, request.speed, robot=choice.robot_setting)
    elif request.backend in ROBOT_BACKENDS:
        config = ControllerConfig.approach(surface, request.speed)
    else:
        config = ControllerConfig.approach(surface, request.speed, posture_weight=0.0)
    return config.for_choice(choice)


def _agree(choice: RobotChoice, what: str, other: RobotChoice, source: str) -> None:
    """Bad input when ``other`` (from ``source``) differs from ``choice`` (from ``what``)."""
    if not choice.same_as(other):
        raise BadInputError(
            f"the robot and tool of {what} ({choice.robot.name}, {choice.tool.name}) differ from "
            f"{source} ({other.robot.name}, {other.tool.name})"
        )


def check_request(request: RunRequest) -> None:
    if request.backend not in BACKENDS:
        raise BadInputError(f"--backend {request.backend!r}: choose from {', '.join(BACKENDS)}")
    name = request.choice.robot.name
    robot = BACKEND_ROBOTS.get(request.backend)
    if robot is not None and name != robot:
        raise BadInputError(
            f"--backend {request.backend} drives the {robot} only, not the {name}: "
            f"use --robot {robot}, or --backend {'panda' if robot == 'fr3' else 'franka'} for the {name}"
        )
    robot = request.choice.robot
    if robot.floating and request.backend != "sim":
        raise BadInputError(f"the {name} has a floating base: it runs on --backend sim only, not {request.backend}")
    named = robot.stances if robot.floating else robot.postures
    if request.posture is not None and request.posture not in named:
        raise BadInputError(f"--posture {request.posture!r} is unknown; known: {', '.join(named)}")
    approach_speed(request.speed, "--speed")
    number_in_range(request.duration, 0.0, MAX_DURATION, "--duration", "s", low_open=True)
    if request.backend in ROBOT_BACKENDS and not request.robot_ip:
        raise BadInputError(f"--backend {request.backend} needs --robot-ip IP")
    if request.backend == "replay" and not request.dataset:
        raise BadInputError("--backend replay needs --dataset DIR (and optionally --trial ID)")
    for option, value, backend in (("--plant", request.plant_file, "sim"), ("--dataset", request.dataset, "replay"),
                                   ("--trial", request.trial, "replay")):
        if value is not None and request.backend != backend:
            raise BadInputError(f"{option} applies to --backend {backend} only, not {request.backend}")


def start_posture(request: RunRequest, model: RobotModel, config: ControllerConfig) -> np.ndarray:
    """The posture's configuration (of the configuration's robot and tool) with the contact
    point ``SIM_START_DISTANCE`` in front of the surface."""
    try:
        posture = config.choice.posture(request.posture or config.choice.robot.default_posture)
        return approach_start(model, posture.q, config.surface.surface(), SIM_START_DISTANCE)
    except UnreachableStartError as error:
        raise BadInputError(str(error)) from None


@dataclass(frozen=True)
class Backend:
    """What a run drives: the ``robot`` (a backend), its controller ``config`` (whose ``choice``
    is the robot and tool modelled), the run's ``duration`` (s), the one ``model`` of the run
    and, for a real robot, the start posture ``q_start`` it moves to first and the ``collision``
    thresholds set on it (None otherwise)."""

    robot: RobotInterface
    config: ControllerConfig
    duration: float
    model: RobotModel
    q_start: np.ndarray | None = None
    stance: np.ndarray | None = None  # a floating base's standing configuration (its support)
    collision: CollisionThresholds | None = None


def build_backend(request: RunRequest) -> Backend:
    """The backend of the request, with the run's model built once. A robot is connected,
    configured (``[libfranka]``, the collision thresholds from the impact planned at the start
    posture: ``collision_thresholds``) and its model checked here; its posture task holds the
    start posture."""
    if request.backend in ROBOT_BACKENDS:
        Robot = FrankaRobot if request.backend == "franka" else PandaRobot
        config = controller_config(request)
        model = config.choice.shared_model
        q_start = start_posture(request, model, config)
        speed = asked_speed(config)
        peaks = None if speed is None else predicted_peaks(model, q_start, config.surface.normal, speed, config.impact)
        collision = impact_thresholds(config.libfranka, peaks)
        robot = Robot.connect(request.robot_ip, config.libfranka, request.realtime, model, collision)
        robot.check_model(model)
        return Backend(robot, with_posture_target(config, q_start), request.duration, model, q_start, collision=collision)
    if request.backend == "replay":
        trial, header = load_trial(request.dataset, request.trial)
        if not request.choice.is_default:
            _agree(header.choice, "the dataset's manifest", request.choice, "--robot/--tool")
        speed = trial.entry.reference_normal_speed
        config = controller_config(RunRequest(**{**request.__dict__, "speed": speed}), header.surface, header.choice)
        duration = len(trial.log) * header.control_period
        return Backend(ReplayRobot(trial, header.control_period), config, duration, config.choice.shared_model)
    if request.choice.robot.floating:
        return standing_backend(request)
    config = controller_config(request)
    choice = config.choice
    try:
        plant = None if request.plant_file is None else PlantParameters.from_json(request.plant_file)
    except PlantParameterError as error:
        raise BadInputError(f"--plant: {error}") from None
    model = choice.shared_model
    q0 = start_posture(request, model, config)
    scene = build_scene(config.surface.surface(), plant, robot=choice.robot, tool=choice.tool)
    robot = SimRobot(scene, q0, np.zeros(model.nv), config.dt, paced=not request.unpaced)
    return Backend(robot, config, request.duration, model)


def standing_backend(request: RunRequest) -> Backend:
    """The sim backend of a floating-base robot: standing in the stance ``--posture`` (default:
    its description's default), the wall ``SIM_START_DISTANCE`` ahead of its contact point along
    +x (the stances' approach), settled on its feet for ``SETTLE`` s under the standing servo."""
    if request.config_file is not None or request.plant_file is not None:
        raise BadInputError("a floating-base robot runs its own preset on the nominal plant: --config and --plant do not apply")
    choice = request.choice
    model = choice.shared_model
    placement = choice.robot.stances[request.posture or choice.robot.default_posture]
    stance = stance_posture(model, placement)
    contact = model.terms(stance).contact_point
    surface = Surface(contact + np.array([SIM_START_DISTANCE, 0.0, 0.0]), STANDING_NORMAL)
    config = controller_config(request, surface)
    scene = build_humanoid_scene(model, wall_x=float(surface.point[0]), stance=placement)
    start = stance.copy()
    start[2] -= SINK  # the soft floor carries the weight from the first step
    support = StandingSupport(model, scene.base_nq, scene.base_nv)
    robot = SimRobot(scene, start, np.zeros(model.nv), config.dt, paced=not request.unpaced, standing=support, gain=SERVO_GAIN)
    robot.hold(SETTLE)
    return Backend(robot, config, request.duration, model, stance=stance)


def move_to_start(robot: RobotInterface, model: RobotModel, config: ControllerConfig, q_start, signals: StopSignals) -> dict:
    """Run the move to ``q_start`` (``start_move``); its report. A move that does not end at
    rest on its own (watchdog, robot error, stop request) ends the run before the session."""
    move = StartMove(q_start, model, config.dt, robot.read(), config.surface.surface())
    loop = ControlLoop(robot, move, CommandFilter.for_robot(model, config.dt), deadline=float("inf"))
    signals.loop = loop
    result = loop.run(move.duration)
    if result.interrupted:  # a stop signal: the command is interrupted, not given bad input
        raise KeyboardInterrupt
    if result.watchdog_trips:
        raise BadInputError(
            f"the move to the start posture ended early ({result.watchdog_reason}); the robot braked to a stop"
        )
    return {
        "duration": move.duration, "cycles": result.cycles, "final_error": move.final_error(result.log.q[-1]),
        "retreat": move.path.retreat, "clearance": move.path.clearance,
    }


def run(request: RunRequest, say: Callable[[str], None] = lambda line: None) -> tuple[dict, LoopResult]:
    """Run the request with the model of the configuration's robot and tool; (report, result). Ctrl-C,
    SIGTERM or SIGHUP brakes to a stop and keeps the log (``result.interrupted``). The log
    directory is checked before the robot moves; a robot's collision thresholds are told to
    ``say`` (one line) once it is configured, and it moves to the start posture first."""
    check_request(request)
    backend = build_backend(request)
    if backend.collision is not None:
        say(backend.collision.reason)
    robot, config, duration, model, q_start = (
        backend.robot, backend.config, backend.duration, backend.model, backend.q_start
    )
    run_log = RunLog(request.log, log_header(config)) if request.log else None
    deadline = request.deadline
    if deadline is None and (request.backend == "replay" or request.unpaced or not request.realtime):
        # offline, or a simulated robot without a real-time kernel: the plant waits for the controller
        deadline = float("inf")
    with StopSignals() as signals:
        start_move = None if q_start is None else move_to_start(robot, model, config, q_start, signals)
        session = ImpactSession(config, model, backend.stance)
        loop = ControlLoop(
            robot, session, CommandFilter.for_robot(model, config.dt), deadline=deadline,
            max_overruns=request.max_overruns,
        )
        signals.loop = loop
        result = loop.run(duration)
    log_path = write_log(run_log, request, config, result) if run_log is not None else None
    report_ = report(result, config, log_path)
    report_["robot"] = robot.report()
    report_["start_move"] = start_move
    if log_path is not None and backend.collision is not None:
        run_log.add_robot(report_["robot"], start_move)
    return report_, result


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
        "missed_in_a_row": result.missed_in_a_row,
        "robot_stop_reason": result.robot_stop_reason,
        "impact": {
            "detected": detector.detected,
            "time": detector.t_detect,
            "detection_latency_ms": latency,
            "contact_speed": session.contact_speed(),
            "residual": session.residual_source,
        },
        "speed": speed_report(config, session),
        "phase": result.phase,
        "log": log_path,
    }


SPEED_SHORTFALL = 0.02
"""A contact speed this fraction below the asked one was capped by the controller."""


EQUALITY_CONSTRAINTS = ("held_contacts",)
"""Constraints whose rows are equalities: always active, they cap nothing."""


def asked_speed(config: ControllerConfig) -> float | None:
    """The contact-approach task's speed (m/s); None without one."""
    return next(
        (float(t.params["speed"]) for t in config.tasks if t.type == "contact_approach" and "speed" in t.params), None
    )


def speed_report(config: ControllerConfig, session: ImpactSession) -> dict:
    """The approach speed asked (the contact-approach task's, m/s; None without one), the contact
    speed (m/s; None without an impact), and, when the contact came slower than asked, the
    inequality constraints active at the approach's last command: what capped the speed (none:
    the approach had not reached its speed, or its task traded it off against the others)."""
    asked = asked_speed(config)
    contact = session.contact_speed()
    last = session.last_approach
    capped = asked is not None and contact is not None and contact < (1.0 - SPEED_SHORTFALL) * asked
    return {
        "asked": asked,
        "contact": contact,
        "slower": bool(capped),
        "capped_by": sorted(set(last.active_constraints) - set(EQUALITY_CONSTRAINTS)) if capped and last else [],
    }


def log_header(config: ControllerConfig) -> DatasetHeader:
    return DatasetHeader.of(config.choice, config.surface.surface(), config.dt)


def after(log: TrialLog, t_start: float) -> TrialLog:
    """The samples of a log without force from ``t_start`` on."""
    k = int(np.searchsorted(log.t, t_start))
    return TrialLog(log.t[k:], log.q[k:], log.dq[k:], log.tau[k:], log.dq_cmd[k:])


def write_log(run_log: RunLog, request: RunRequest, config: ControllerConfig, result: LoopResult) -> str:
    """Add the run as one trial to its dataset; the trial file's path.

    A log without a force measurement (a robot's) is written from the end of the detector's
    contact-free reference window on, and at most ``IMPACT_LEAD`` before the detected impact: the
    offline torque rule (``controller.measured.impact``) reads a trial that starts in the
    approach, and would take the start-up of a velocity-servoed arm from rest or the approach's
    acceleration (the joint torque following the commanded acceleration) for an impact."""
    speed = next(
        (float(t.params.get("speed", 0.0)) for t in config.tasks if t.type == "contact_approach"), request.speed
    )
    log = result.log
    t_reference = result.session.detector.t_calibrated
    t_detect = result.session.detector.t_detect
    if not log.has_force and t_reference is not None:
        log = after(log, t_reference if t_detect is None else max(t_reference, t_detect - IMPACT_LEAD))
    return run_log.add(
        log,
        speed,
        posture=request.posture if request.backend == "sim" else None,
        # without a force log the contact start is not measured: the online detection time is
        # later by the detector's latency, so ``impact_time`` is left out and the offline rule
        # finds the contact in the torques (``dataset validate``, ``diagnose``)
        impact_time=contact_start(result) if log.has_force else None,
    )
