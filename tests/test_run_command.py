"""``impactqp run``: the JSON report, and one line on stderr with exit code 2 for bad input."""

import importlib.util
import json
import signal
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

from impactqp.controller.measured.dataset import read_dataset
from impactqp.scenarios import run as run_module
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_ROBOT_WOULD_STOP
from conftest import JOINTS, ForwardingRobot, g1_dataset

HAS_PYLIBFRANKA = importlib.util.find_spec("pylibfranka") is not None


def test_sim_run_prints_the_report_and_writes_a_dataset(tmp_path, capsys):
    code = main(["run", "--backend", "sim", "--unpaced", "--duration", "0.45", "--log", str(tmp_path), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) >= {"cycles", "overruns", "cycle_us", "watchdog_trips", "impact", "phase", "log"}
    assert set(report["cycle_us"]) == {"p50", "p99", "max"}
    assert set(report["impact"]) == {"detected", "time", "detection_latency_ms", "contact_speed", "residual"}
    assert report["impact"]["detected"]
    assert (tmp_path / "dataset.json").exists() and report["log"].endswith("run0000.csv")
    assert main(["dataset", "validate", str(tmp_path)]) == 0
    capsys.readouterr()
    err = one_error_line(capsys, ["run", "--backend", "replay", "--dataset", str(tmp_path), "--trial", "t9"])
    assert "replay trial 't9' is not in" in err and "run0000" in err


def one_error_line(capsys, argv):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and err.startswith("impactqp: error:")
    return err


@pytest.mark.skipif(not HAS_PYLIBFRANKA, reason="pylibfranka is not installed: pip install -e '.[franka]'")
def test_franka_without_a_robot_fails_with_one_line(capsys, no_robot_address):
    err = one_error_line(capsys, ["run", "--backend", "franka", "--robot", "fr3", "--robot-ip", no_robot_address])
    # either legitimate error: which one libfranka raises first depends on the machine, not on us
    assert f"no robot answers at {no_robot_address}" in err or "real-time scheduling is not available" in err


def test_franka_without_pylibfranka_says_how_to_install_it(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pylibfranka", None)  # makes `import pylibfranka` fail
    err = one_error_line(capsys, ["run", "--backend", "franka", "--robot", "fr3", "--robot-ip", "127.0.0.1"])
    assert "pip install -e '.[franka]'" in err


@pytest.mark.parametrize(("backend", "robot", "right"), [("franka", "panda", "fr3"), ("panda", "fr3", "panda")])
def test_a_backend_for_another_robot_is_bad_input_before_connecting(capsys, monkeypatch, backend, robot, right):
    monkeypatch.setattr(run_module, "build_backend", lambda *_: pytest.fail("connected"))
    err = one_error_line(capsys, ["run", "--backend", backend, "--robot", robot, "--robot-ip", "127.0.0.1"])
    assert f"--backend {backend} drives the {right} only, not the {robot}: use --robot {right}" in err
    assert "unknown robot 'kuka'; choose from panda, fr3, ur5, g1" in one_error_line(capsys, ["run", "--robot", "kuka"])


def test_bad_input_gets_one_line(tmp_path, capsys):
    assert "does not exist" in one_error_line(capsys, ["run", "--config", str(tmp_path / "missing.toml")])
    bad = tmp_path / "bad.toml"
    bad.write_text("nonsense_key = 1\n")
    assert "unknown configuration keys" in one_error_line(capsys, ["run", "--config", str(bad)])
    assert "needs --robot-ip" in one_error_line(capsys, ["run", "--backend", "franka", "--robot", "fr3"])
    assert "dataset.json" in one_error_line(capsys, ["run", "--backend", "replay", "--dataset", str(tmp_path)])
    assert "--speed" in one_error_line(capsys, ["run", "--speed", "-1"])


class SignalAt(ForwardingRobot):
    """A backend that delivers ``sig`` to this process when its state ``at`` is read (the user
    pressing Ctrl-C, or a supervisor sending SIGTERM, mid-run)."""

    def __init__(self, robot, sig, at):
        super().__init__(robot)
        self.sig, self.at, self.reads = sig, at, 0

    def read(self):
        self.reads += 1
        if self.reads == self.at:
            signal.raise_signal(self.sig)
        return self.robot.read()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_brakes_keeps_the_log_and_exits_130(sig, tmp_path, capsys, monkeypatch):
    build = run_module.build_backend

    def build_with_signal(request):
        backend = build(request)
        return replace(backend, robot=SignalAt(backend.robot, sig, at=150))

    monkeypatch.setattr(run_module, "build_backend", build_with_signal)
    code = main(["run", "--unpaced", "--duration", "5", "--log", str(tmp_path), "--json"])
    out, err = capsys.readouterr()
    assert code == 130 and "interrupted" in err and len(err.strip().splitlines()) == 1
    report = json.loads(out)
    assert report["phase"] == "stop" and 150 < report["cycles"] < 5000
    trial = read_dataset(tmp_path).trials[0]
    assert len(trial.log) == report["cycles"]
    assert np.max(np.abs(trial.log.dq_cmd[149])) > 0.01 and np.all(trial.log.dq_cmd[-1] == 0.0)


def test_an_unusable_log_directory_is_refused_before_the_robot_moves(tmp_path, capsys, monkeypatch):
    moved = []
    build = run_module.build_backend

    def build_and_watch(request):
        backend = build(request)
        robot = backend.robot
        robot.write = lambda dq_cmd, write=robot.write: (moved.append(1), write(dq_cmd))
        return backend

    monkeypatch.setattr(run_module, "build_backend", build_and_watch)
    blocker = tmp_path / "a file"
    blocker.write_text("x")
    assert "--log" in one_error_line(capsys, ["run", "--unpaced", "--duration", "0.2", "--log", str(blocker / "d")])
    assert moved == []
    other = tmp_path / "other"
    assert main(["run", "--unpaced", "--duration", "0.05", "--log", str(other)]) == 0
    header = json.loads((other / "dataset.json").read_text())
    header["control_period"] = 0.002
    (other / "dataset.json").write_text(json.dumps(header))
    moved.clear()
    capsys.readouterr()
    assert "another header" in one_error_line(capsys, ["run", "--unpaced", "--duration", "0.05", "--log", str(other)])
    assert moved == []


class LateOrBroken(ForwardingRobot):
    """A backend whose cycle ``at`` takes 7 periods (``fault="late"``) or whose state ``at`` is
    NaN (``fault="nan"``)."""

    def __init__(self, robot, fault, at):
        super().__init__(robot)
        self.fault, self.at, self.reads = fault, at, 0

    def read(self):
        self.reads += 1
        state = self.robot.read()
        if self.reads == self.at and self.fault == "nan":
            state = replace(state, dq=np.full(JOINTS, np.nan))
        return state

    def write(self, dq_cmd):
        if self.reads == self.at and self.fault == "late":
            time.sleep(7 * self.period)
        self.robot.write(dq_cmd)


@pytest.mark.parametrize("fault, options", [("late", []), ("nan", ["--unpaced"])])
def test_a_run_a_real_robot_would_not_have_finished_exits_3_and_says_why(fault, options, tmp_path, capsys, monkeypatch):
    build = run_module.build_backend

    def build_faulty(request):
        backend = build(request)
        return replace(backend, robot=LateOrBroken(backend.robot, fault, 100))

    monkeypatch.setattr(run_module, "build_backend", build_faulty)
    code = main(["run", *options, "--duration", "0.3", "--log", str(tmp_path), "--json"])
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert code == EXIT_ROBOT_WOULD_STOP
    assert err.strip().splitlines() == [err.strip()] and "would have stopped a real robot" in err
    assert report["robot_stop_reason"] and report["robot_stop_reason"] in err
    if fault == "late":
        assert report["missed_in_a_row"] >= 6 and report["overruns"] >= 1
    else:
        assert "non-finite" in report["watchdog_reason"]


def test_a_robot_run_keeps_a_posture_task_on_the_start_posture_in_both_phases():
    from impactqp.controller.config import post_impact_config

    q_start = np.linspace(-0.5, 0.5, JOINTS)
    config = run_module.with_posture_target(run_module.controller_config(run_module.RunRequest(backend="franka")), q_start)
    for phase in (config, post_impact_config(config)):
        (posture,) = [t for t in phase.tasks if t.type == "posture"]
        assert posture.params["weight"] > 0.0 and posture.params["target"] == q_start.tolist()
    sim = run_module.controller_config(run_module.RunRequest(backend="sim"))
    assert [t.params["weight"] for t in sim.tasks if t.type == "posture"] == [0.0]  # the sim run as before
    kept = [0.1] * JOINTS  # a configured target is the user's
    configured = run_module.with_posture_target(replace_posture_target(config, kept), q_start)
    assert [t.params["target"] for t in configured.tasks if t.type == "posture"] == [kept]


def replace_posture_target(config, target):
    from dataclasses import replace

    from impactqp.controller.config import TaskConfig

    tasks = [TaskConfig(t.type, {**t.params, "target": target}) if t.type == "posture" else t for t in config.tasks]
    return replace(config, tasks=tasks)


def test_every_option_of_run_is_a_request_field_of_the_same_name_and_every_field_is_documented():
    from dataclasses import fields

    from impactqp.scenarios.cli.run_command import run_command
    from impactqp.scenarios.run import RunRequest

    names = {f.name for f in fields(RunRequest)}
    options = {p.name for p in run_command.params} - {"as_json"}
    # --robot and --tool arrive together as one field, the RobotChoice ``choice``
    assert {"robot", "tool"} <= options and "choice" in names
    assert options - {"robot", "tool"} <= names
    for name in names:
        assert f"\n    {name}\n" in RunRequest.__doc__, name
    assert RunRequest().unpaced is False and RunRequest().log is None


def test_replaying_a_g1_dataset_is_one_line_of_bad_input(tmp_path, capsys):
    g1_dataset(tmp_path)
    err = one_error_line(capsys, ["run", "--backend", "replay", "--dataset", str(tmp_path)])
    assert "its robot g1 has a floating base" in err


@pytest.mark.parametrize("robot", ["panda", "ur5"])
def test_a_run_builds_the_robot_model_once(robot, tmp_path, monkeypatch):
    """The start posture (the robot's default posture), the backend, the controller and the
    command filter share one model, on any arm."""
    from impactqp.controller.model import robot as robot_module

    built = []
    build = robot_module.RobotModel.__init__
    monkeypatch.setattr(robot_module.RobotModel, "__init__", lambda self, *a, **k: built.append(1) or build(self, *a, **k))
    assert main(["run", "--robot", robot, "--unpaced", "--duration", "0.05", "--log", str(tmp_path)]) == 0
    assert len(built) == 1


def test_a_run_asked_too_fast_says_the_controller_capped_it_and_by_what(capsys, tmp_path):
    """Asked 1 m/s at elbow_up, the contact comes at the posture's highest feasible speed: the
    report gives both speeds and the constraints active at the approach's last command."""
    log = ["--log", str(tmp_path)]  # not the working directory's default out/run
    code = main(["run", "--backend", "sim", "--unpaced", "--duration", "0.5", "--speed", "1.0", "--json", *log])
    assert code == 0
    speed = json.loads(capsys.readouterr().out)["speed"]
    assert speed["asked"] == 1.0 and 0.0 < speed["contact"] < 0.98
    assert any(name.startswith(("post_impact_velocity", "impulsive_torque")) for name in speed["capped_by"])
    assert main(["run", "--backend", "sim", "--unpaced", "--duration", "0.5", "--speed", "1.0", *log]) == 0
    assert "asked 1.000 m/s, hit at" in capsys.readouterr().out


def test_the_standing_g1_runs_on_the_sim_backend_detects_its_impact_and_stays_up(tmp_path, capsys):
    """``run --robot g1 --backend sim``: the G1's own preset (balance tasks, held contacts,
    capture region) in the same 1 kHz loop, session and log as the arms; the impact is detected
    from the jump of the measured velocity within a few periods of the first wall contact, the
    log validates, and the robot is still standing upright at the end."""
    from impactqp.controller.measured.dataset import read_header

    code = main(["run", "--robot", "g1", "--backend", "sim", "--unpaced", "--duration", "0.7", "--log", str(tmp_path), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["watchdog_trips"] == 0 and report["robot"] == {}
    assert report["impact"]["detected"] and report["impact"]["residual"] == "velocity_jump"
    assert 0.0 <= report["impact"]["detection_latency_ms"] <= 5.0
    assert main(["dataset", "validate", str(tmp_path)]) == 0
    capsys.readouterr()
    assert read_header(tmp_path).robot == "g1"
    log = np.genfromtxt(tmp_path / "run0000.csv", delimiter=",", names=True)
    assert log["base_z"][-1] > 0.95 * log["base_z"][0]  # the pelvis height
    # upright: the quaternion's x and y stay small (a tilt below 11 degrees)
    assert np.all(np.abs(log["base_qx"]) < 0.1) and np.all(np.abs(log["base_qy"]) < 0.1)


def test_the_standing_g1_s_start_is_no_impact_and_its_contact_is_one(tmp_path, capsys):
    """Asked 0.4 m/s, the approach's start was read as the impact 2 ms into the run (the
    command's hand speed ran ahead of a body that had not yet followed it) and the robot never
    reached the wall; now the impact is detected at the wall's first contact, and the robot
    stands through it (its pelvis pitches back: docs/robot-loop.md)."""
    from impactqp.controller.model.humanoid_stance import edge_margins, support_polygon
    from impactqp.controller.model.robot import RobotModel

    code = main(["run", "--robot", "g1", "--backend", "sim", "--unpaced", "--speed", "0.4", "--duration", "0.7",
                 "--log", str(tmp_path), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["watchdog_trips"] == 0
    assert report["impact"]["detected"] and 0.0 <= report["impact"]["detection_latency_ms"] <= 5.0
    assert report["impact"]["contact_speed"] > 0.1
    # it stands: its centre of mass stays over its feet, at its height, to the end of the run
    g1, log = RobotModel("g1"), np.genfromtxt(tmp_path / "run0000.csv", delimiter=",", names=True)
    base = ["base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw"]
    joints = [f"q{i + 1}" for i in range(g1.n_joints)]
    postures = [np.array([row[name] for name in base + joints]) for row in log[::50]]
    coms = [g1.terms(q, check_limits=False).com for q in postures]
    assert all(np.all(edge_margins(support_polygon(g1, q), com) > 0.0) for q, com in zip(postures, coms))
    assert all(com[2] > 0.95 * coms[0][2] for com in coms)


@pytest.mark.parametrize("args, message", [
    (["--backend", "replay", "--dataset", "DIR"], "runs on --backend sim only"),
    (["--backend", "sim", "--plant", "PLANT"], "--config and --plant do not apply"),
    (["--backend", "sim", "--posture", "elbow_up"], "--posture 'elbow_up' is unknown"),
])
def test_what_a_standing_robot_run_cannot_take_is_one_line(tmp_path, capsys, args, message):
    args = [str(tmp_path) if a == "DIR" else str(tmp_path / "p.json") if a == "PLANT" else a for a in args]
    (tmp_path / "p.json").write_text("{}")
    err = one_error_line(capsys, ["run", "--robot", "g1", *args])
    assert message in err
