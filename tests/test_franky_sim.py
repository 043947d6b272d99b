"""The whole impact session through the real Franka network protocol: our ``franka`` backend
(``pylibfranka``) against a franky-sim server (MuJoCo FR3 behind libfranka's TCP/UDP protocol)
with a wall and the contact tool in its scene, in its own process group.

The server runs in lockstep with the client during a motion (one physics step per command,
``sim.franky_sim``), so a loaded machine slows a run but does not change it: every bound here
counts control cycles, never wall time, and nothing about timing is asserted. The fixture owns
the server processes and kills them in its finalizer, also when a test fails; a failed test
shows the servers' output.
"""

import json
import os
import time

import numpy as np
import pytest

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.config import ControllerConfig
from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.impact import WINDOW_AFTER
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.robot_config import DEFAULT_FORCE_THRESHOLDS, DEFAULT_TORQUE_THRESHOLDS, RobotConfig
from impactqp.controller.runtime.collision_thresholds import impact_thresholds, predicted_peaks
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.runtime.franka_backend import FrankaRobot
from impactqp.controller.runtime.loop import STOPPING, ControlLoop
from impactqp.controller.runtime.run_log import RunLog
from impactqp.controller.runtime.session import OBSERVER, ImpactSession
from impactqp.controller.runtime.start_move import START_CLEARANCE
from impactqp.scenarios.cli import main
from impactqp.scenarios.run import IMPACT_LEAD, RunRequest, log_header, start_posture, write_log
from impactqp.sim.franky_sim import FREE_PERIOD, LOCKSTEP_PATIENCE, FrankySimServer

pytest.importorskip("pylibfranka", reason="pylibfranka is not installed: pip install -e '.[franka]'")
pytest.importorskip("franky_sim", reason="franky-sim is not installed: pip install -e '.[test]'")

ROBOT = "fr3"  # franky-sim serves an FR3
POSTURE = ROBOTS[ROBOT].postures["elbow_up"]
START_DISTANCE = 0.05
SPEED = 0.15
WALL_TOLERANCE = 0.005  # m: the tool's predicted contact point at the detection vs the wall
WRIST_DRIFT = 0.05  # rad: the posture task holds the wrist near the start posture
LOST_AT = 150  # the motion command at which the server stops
AWAY = 0.25  # m: the server's arm starts facing the wall this far from it, the run moves it closer


@pytest.fixture
def franky_sim(tmp_path, request):
    """``start(q0)`` -> a listening server with the posture's wall; every one is killed at
    teardown, and a failed test shows their output (``conftest.pytest_runtest_makereport``)."""
    servers = request.node.franky_sim_servers = []

    def start(q0, stop_after_commands=None):
        server = FrankySimServer(
            tmp_path / f"server{len(servers)}", POSTURE.surface.point, POSTURE.surface.normal, q0,
            stop_after_commands=stop_after_commands,
        )
        servers.append(server)
        server.start()
        return server

    yield start
    for server in servers:
        server.stop()


@pytest.fixture(scope="module")
def model():
    return RobotModel(ROBOT)  # with the default tool, the sphere the server's scene carries


def session_loop(robot, model):
    config = ControllerConfig.approach(POSTURE.surface, SPEED, posture_weight=0.0)
    config.robot, config.tool = ROBOT, "impact_tip"  # the log's manifest names the robot driven
    session = ImpactSession(config, model)
    return config, ControlLoop(robot, session, CommandFilter.for_robot(model, config.dt), deadline=float("inf"))


def test_the_session_detects_the_wall_retracts_and_logs_through_the_franka_protocol(franky_sim, model, tmp_path, capsys):
    q0 = approach_start(model, POSTURE.q, POSTURE.surface, START_DISTANCE)
    server = franky_sim(q0)
    own = (os.sched_getscheduler(0), os.sched_getparam(0))
    robot = FrankaRobot.connect(server.hostname, realtime=False, model=model)
    # libfranka raised this thread to real time when it opened the robot: given back at once
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == own
    assert robot.check_model(model) <= RobotConfig().max_model_difference
    config, loop = session_loop(robot, model)
    run_log = RunLog(str(tmp_path / "log"), log_header(config))
    result = loop.run(1.0)
    session = result.session
    assert result.watchdog_trips == 0, result.watchdog_reason
    assert session.residual_source == OBSERVER  # franky-sim reports tau_J as tau_ext_hat_filtered
    assert session.detector.detected and result.phase == STOPPING
    assert "retract" in result.phases
    log = result.log
    distance = np.array([POSTURE.surface.signed_distance(model.contact_point(q)) for q in log.q])
    detected = int(np.searchsorted(log.t, session.detector.t_detect))
    assert abs(distance[detected]) <= WALL_TOLERANCE
    assert np.all(distance[:detected] > -WALL_TOLERANCE)  # no earlier contact went unnoticed
    assert distance[-1] > distance[detected] + WALL_TOLERANCE  # retracted
    assert 0.5 * SPEED < session.contact_speed() <= SPEED * 1.05
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == own  # the motion's ended: this thread's own again
    t_contact = server.contact_time()  # the server's first wall contact, on the states' clock
    assert t_contact is not None and t_contact <= session.detector.t_detect <= t_contact + WINDOW_AFTER
    write_log(run_log, RunRequest(backend="franka", choice=RobotChoice.of(ROBOT, "impact_tip"), robot_ip=server.hostname, speed=SPEED), config, result)
    capsys.readouterr()
    assert main(["dataset", "validate", str(tmp_path / "log")]) == 0, capsys.readouterr().err


def test_a_lost_connection_ends_the_run_in_one_line_and_keeps_the_log(franky_sim, model, tmp_path):
    q0 = approach_start(model, POSTURE.q, POSTURE.surface, START_DISTANCE)
    server = franky_sim(q0, stop_after_commands=LOST_AT)  # the server stops when command LOST_AT arrives
    robot = FrankaRobot.connect(server.hostname, realtime=False, model=model)
    config, loop = session_loop(robot, model)
    result = loop.run(1.0)
    assert loop.robot_failed
    assert result.watchdog_trips == 1 and result.watchdog_reason.startswith("robot error: ")
    assert "\n" not in result.watchdog_reason
    # every cycle up to the unanswered command is logged with its state, then the read that got
    # no state as NaN values (no measurement) with its braking command, which nothing received
    assert result.cycles == LOST_AT + 1
    assert np.all(np.isfinite(result.log.q[:-1])) and np.all(np.isnan(result.log.q[-1]))
    assert np.all(np.diff(result.log.t) > 0.0)
    # the trial written from that log ends at the last measured sample: no NaN row in the dataset
    from impactqp.controller.measured.dataset_check import validate

    path = RunLog(str(tmp_path / "lost"), log_header(config)).add(result.log, SPEED, None, None)
    assert path is not None
    (trial,) = read_dataset(tmp_path / "lost").trials  # reading refuses a NaN value
    # the torque of the last answered period comes with the next state, which never came: the trial
    # ends one sample before the unanswered read
    assert len(trial.log) == LOST_AT - 1 and np.allclose(trial.log.q, result.log.q[:-2], rtol=1e-9, atol=1e-12)
    problems = validate(tmp_path / "lost")
    assert not any("NaN" in problem for problems_of in problems.values() for problem in problems_of)


def test_a_client_that_misses_its_cycles_reads_the_newer_state_the_lockstep_sent_on_its_own(franky_sim, model):
    """A client that stops answering during a motion (here for 4 x ``LOCKSTEP_PATIENCE``) does not
    stall the lockstep: the server steps and sends states on its own clock, as a robot would, so
    the client's next read returns a newer state (libfranka keeps the newest) instead of its 1 s
    receive timeout, and the motion then goes on in lockstep and finishes."""
    q0 = approach_start(model, POSTURE.q, POSTURE.surface, START_DISTANCE)
    robot = FrankaRobot.connect(franky_sim(q0).hostname, realtime=False, model=model)
    zero = np.zeros(model.nv)
    before = robot.start()
    robot.write(zero)
    answered = robot.read()
    robot.write(zero)
    time.sleep(4 * LOCKSTEP_PATIENCE)  # a missed stretch: no read, no command
    after = robot.read()
    assert answered.t > before.t and after.t >= answered.t + 2 * FREE_PERIOD - 1e-9
    times = [after.t]
    for _ in range(5):
        robot.write(zero)
        times.append(robot.read().t)
    assert np.all(np.diff(times) > 0.0)
    robot.stop()


def contact_distance_at(log_file, t, model) -> float:
    """The declared tool's contact point's signed distance to the wall at the logged state of time ``t``."""
    log = np.loadtxt(log_file, delimiter=",", skiprows=1)
    k = int(np.searchsorted(log[:, 0], t))
    return POSTURE.surface.signed_distance(model.contact_point(log[k, 1:8]))


def test_impactqp_run_moves_to_the_start_then_runs_the_session_against_the_server(franky_sim, model, tmp_path, capsys):
    server = franky_sim(approach_start(model, POSTURE.q, POSTURE.surface, AWAY))
    argv = ["run", "--backend", "franka", "--robot", ROBOT, "--robot-ip", server.hostname, "--realtime", "ignore", "--json"]
    # the model check refuses a robot whose mass matrix differs by more than the limit, in one line, before any motion
    strict = tmp_path / "strict.toml"
    strict.write_text(f'robot = "{ROBOT}"\n[libfranka]\nmax_model_difference = 1e-6\n')
    assert main(argv + ["--config", str(strict), "--log", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "mass matrix differs" in err and "max_model_difference" in err
    code = main(argv + ["--log", str(tmp_path / "log"), "--duration", "1.0"])
    out, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(out)
    assert report["overruns"] == 0 and report["robot_stop_reason"] == ""  # --realtime ignore: no deadline
    assert report["watchdog_trips"] == 0, report["watchdog_reason"]
    assert report["impact"]["detected"] and report["impact"]["residual"] == OBSERVER
    assert report["phase"] == STOPPING
    robot = report["robot"]
    assert 0.0 < robot["model_difference"] <= RobotConfig().max_model_difference
    assert robot["reflex"] == [] and not robot["recovered"]
    assert robot["command_success_rate"] == 1.0 and robot["missed_packets"] >= 0
    request = RunRequest(backend="franka", choice=RobotChoice.of(ROBOT, "impact_tip"))
    q_start = start_posture(request, model, ControllerConfig.approach(POSTURE.surface))
    move = report["start_move"]
    assert move["cycles"] >= int(move["duration"] / 1e-3) and move["final_error"] < 0.01
    # the contact happens where the declared tool predicts it
    assert abs(contact_distance_at(report["log"], report["impact"]["time"], model)) <= WALL_TOLERANCE
    log = np.loadtxt(report["log"], delimiter=",", skiprows=1)
    q_end = log[-1, 1:8]
    assert np.all(np.abs(q_end - q_start)[[4, 6]] < WRIST_DRIFT)
    assert main(["dataset", "validate", str(tmp_path / "log")]) == 0, capsys.readouterr().out
    # one session = one trial of the FR3 with the declared tool, from at most IMPACT_LEAD before the
    # detection, without impact_time (no force log: the offline rule finds the contact)
    dataset = read_dataset(tmp_path / "log")
    assert dataset.header.choice.same_as(RobotChoice.of(ROBOT, "impact_tip")) and len(dataset.trials) == 1
    trial = dataset.trials[0]
    assert trial.entry.impact_time is None and not trial.log.has_force
    assert report["impact"]["time"] - IMPACT_LEAD <= trial.log.t[0] < report["impact"]["time"]
    capsys.readouterr()
    assert main(["diagnose", str(tmp_path / "log"), "--json"]) == 0, capsys.readouterr().err
    diagnosis = json.loads(capsys.readouterr().out)
    assert diagnosis["trials"] == 1 and diagnosis["skipped"] == [] and diagnosis["causes"] == []
    assert diagnosis["message"].startswith("One trial")


def test_impactqp_run_from_franky_sims_home_pose_retreats_from_the_wall_then_runs_the_session(franky_sim, model, tmp_path, capsys):
    """franky-sim's home pose (the hand down, its tool 45.6 mm in front of the default wall): the
    straight joint segment to ``elbow_up``'s start passes the tool behind the wall, so the move
    retreats along the normal first and never touches the wall (the server's first wall contact is
    the session's impact)."""
    from franky_sim.constants import DEFAULT_INITIAL_JOINT_POS  # franky-sim is imported only once it is known installed

    server = franky_sim(np.array(DEFAULT_INITIAL_JOINT_POS))
    argv = ["run", "--backend", "franka", "--robot", ROBOT, "--robot-ip", server.hostname, "--realtime", "ignore", "--json"]
    code = main(argv + ["--log", str(tmp_path / "log"), "--duration", "1.0"])
    out, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(out)
    assert report["watchdog_trips"] == 0, report["watchdog_reason"]
    move = report["start_move"]
    assert move["retreat"] > 0.0 and move["clearance"] >= START_CLEARANCE and move["final_error"] < 0.01
    assert report["impact"]["detected"] and report["phase"] == STOPPING
    t_contact = server.contact_time()
    assert t_contact is not None and t_contact <= report["impact"]["time"] <= t_contact + WINDOW_AFTER
    assert abs(contact_distance_at(report["log"], report["impact"]["time"], model)) <= WALL_TOLERANCE
    # the collision thresholds from the impact predicted at the start posture and the asked speed:
    # said in one line, reported, written beside the trial, and received by the server as computed
    config = ControllerConfig.approach(POSTURE.surface, SPEED)
    q_start = start_posture(RunRequest(backend="franka", choice=RobotChoice.of(ROBOT, "impact_tip")), model, config)
    expected = impact_thresholds(RobotConfig(), predicted_peaks(model, q_start, POSTURE.surface.normal, SPEED, config.impact))
    assert expected.upper_torque != DEFAULT_TORQUE_THRESHOLDS and expected.upper_force != DEFAULT_FORCE_THRESHOLDS
    (said,) = [line for line in err.splitlines() if "collision thresholds" in line]
    assert said == f"impactqp: {expected.reason}"
    assert report["robot"]["collision_thresholds"] == expected.to_dict()
    written = json.loads((tmp_path / "log" / "run0000_robot.json").read_text())
    assert written["robot"]["collision_thresholds"] == expected.to_dict() and written["start_move"] == move
    received = server.collision_behavior()
    for side in ("lower", "upper"):
        for phase in ("acceleration", "nominal"):  # the four-list call sets both phases alike
            np.testing.assert_allclose(received[f"{side}_torque_thresholds_{phase}"], getattr(expected, f"{side}_torque"), rtol=1e-15)
            np.testing.assert_allclose(received[f"{side}_force_thresholds_{phase}"], getattr(expected, f"{side}_force"), rtol=1e-15)
