"""``impactqp run``: the JSON report, and one line on stderr with exit code 2 for bad input."""

import importlib.util
import json
import sys

import pytest

from impactqp.scenarios.cli import main

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
    assert "no such file" in one_error_line(capsys, ["run", "--config", str(tmp_path / "missing.toml")])
    bad = tmp_path / "bad.toml"
    bad.write_text("nonsense_key = 1\n")
    assert "unknown configuration keys" in one_error_line(capsys, ["run", "--config", str(bad)])
    assert "needs --robot-ip" in one_error_line(capsys, ["run", "--backend", "franka"])
    assert "dataset.json" in one_error_line(capsys, ["run", "--backend", "replay", "--dataset", str(tmp_path)])
    assert "--speed" in one_error_line(capsys, ["run", "--speed", "-1"])
