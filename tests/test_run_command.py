"""``impactqp run``: the JSON report, and one line on stderr with exit code 2 for bad input."""

import importlib.util
import json
import signal
import sys

import numpy as np
import pytest

from impactqp.controller.measured.dataset import read_dataset
from impactqp.scenarios import run as run_module
from impactqp.scenarios.cli import main
from conftest import ForwardingRobot

HAS_PYLIBFRANKA = importlib.util.find_spec("pylibfranka") is not None


def test_sim_run_prints_the_report_and_writes_a_dataset(tmp_path, capsys):
    code = main(["run", "--backend", "sim", "--unpaced", "--duration", "0.45", "--log", str(tmp_path), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) >= {"cycles", "overruns", "cycle_us", "watchdog_trips", "impact", "phase", "log"}
    assert set(report["cycle_us"]) == {"p50", "p99", "max"}
    assert set(report["impact"]) == {"detected", "time", "detection_latency_ms", "contact_speed"}
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
def test_franka_without_a_robot_fails_with_one_line(capsys):
    err = one_error_line(capsys, ["run", "--backend", "franka", "--robot-ip", "127.0.0.1"])
    assert "no robot answers at 127.0.0.1" in err


def test_franka_without_pylibfranka_says_how_to_install_it(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pylibfranka", None)  # makes `import pylibfranka` fail
    err = one_error_line(capsys, ["run", "--backend", "franka", "--robot-ip", "127.0.0.1"])
    assert "pip install -e '.[franka]'" in err


def test_bad_input_gets_one_line(tmp_path, capsys):
    assert "does not exist" in one_error_line(capsys, ["run", "--config", str(tmp_path / "missing.toml")])
    bad = tmp_path / "bad.toml"
    bad.write_text("nonsense_key = 1\n")
    assert "unknown configuration keys" in one_error_line(capsys, ["run", "--config", str(bad)])
    assert "needs --robot-ip" in one_error_line(capsys, ["run", "--backend", "franka"])
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
        robot, config, duration = build(request)
        return SignalAt(robot, sig, at=150), config, duration

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
        robot, config, duration = build(request)
        robot.write = lambda dq_cmd, write=robot.write: (moved.append(1), write(dq_cmd))
        return robot, config, duration

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
