"""`impactqp simulate` and `campaign` (and the wall and plant options `max-speed` shares): JSON
contracts, dataset output, video, and one-line errors with exit code 2."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.scenarios.cli import main
from impactqp.controller.measured.dataset_check import validate


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("simulate")
    code = main(["simulate", "--posture", "elbow_left", "--speed", "0.1", "--out", str(out), "--json"])
    return code, out


def test_simulate_json_contract(simulated, capsys):
    code, out = simulated
    code, stdout, _ = run(
        capsys, "simulate", "--posture", "elbow_left", "--speed", "0.1", "--out", str(out), "--json"
    )
    assert code == 0
    report = json.loads(stdout)
    assert report["contact_speed"] == pytest.approx(0.1, rel=0.02)
    assert 0.005 < report["impact_duration"] < 0.05
    assert len(report["impulse"]) == 3 and len(report["dq_jump"]) == JOINTS
    assert set(report["predicted"]) == {"classical", "classical_normal", "gm", "crb"}
    assert all(len(v) == JOINTS for v in report["predicted"].values())
    assert report["violated"] == (report["max_velocity_ratio"] > 1 or report["max_torque_ratio"] > 1)
    assert report["jump_model"] == "crb"


def test_simulate_writes_a_valid_dataset(simulated):
    _, out = simulated
    problems = validate(out)
    assert all(not p for p in problems.values()), problems
    assert "elbow_left_vn100_crb" in problems


def test_simulate_without_jump_constraints_and_tangential(capsys):
    code, stdout, _ = run(
        capsys, "simulate", "--posture", "elbow_up", "--speed", "0.12", "--tangential", "0,0.05,0",
        "--no-jump-constraint",
    )
    assert code == 0
    assert "jump constraints off" in stdout and "simulated jump" in stdout


def test_campaign_json(capsys, tmp_path):
    code, stdout, _ = run(
        capsys, "campaign", "--postures", "elbow_up", "--speeds", "0.1", "--tangential", "none",
        "--out", str(tmp_path), "--json",
    )
    assert code == 0
    table = json.loads(stdout)
    assert len(table["rows"]) == 1 and table["rows"][0]["posture"] == "elbow_up"
    assert (tmp_path / "table1.txt").exists()


@pytest.fixture(scope="module")
def plant_files(tmp_path_factory):
    directory = tmp_path_factory.mktemp("plants")
    (directory / "unknown.json").write_text(json.dumps({"rotor_inertia": 1.0}))
    (directory / "shape.json").write_text(json.dumps({"armature": [0.1, 0.2]}))
    return directory


@pytest.mark.parametrize(
    "args, message",
    [
        (["simulate", "--posture", "nowhere", "--speed", "0.1"], "unknown posture"),
        (["simulate", "--posture", "elbow_up", "--speed", "0"], r"\(0, 3\] m/s"),
        (["simulate", "--posture", "elbow_up", "--speed", "-0.1"], r"\(0, 3\] m/s"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/unknown.json"], "unknown plant parameter"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/shape.json"], f"armature must be {JOINTS} numbers"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/missing.json"], "does not exist"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1.6,0,0"], "out of reach"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-normal", "0,0,0"], "zero"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1,2"], "3 values"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--tangential", "0.1,0,0"], "orthogonal"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--jump-model", "magic"], "magic"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--video", "x.mp4"], "GIF"),
        (["max-speed", "--posture", "nowhere"], "unknown posture"),
        (["max-speed", "--posture", "elbow_up", "--wall-point", "1.6,0,0"], "out of reach"),
        (["max-speed", "--posture", "elbow_up", "--restitution", "1.5"], r"\[0, 1\]"),
        (["max-speed", "--posture", "elbow_up", "--impact-duration", "0"], "one control period"),
        (["max-speed", "--posture", "elbow_up", "--impact-duration", "1e-9"], "one control period"),
        (["simulate", "--posture", "elbow_up", "--speed", "1e9"], r"\(0, 3\] m/s"),
        (["campaign", "--speeds", "50"], r"\(0, 3\] m/s"),
        (["max-speed", "--posture", "elbow_up", "--jobs", "0"], "--jobs"),
        (["max-speed", "--posture", "elbow_up", "--plant", "{dir}/unknown.json"], "unknown plant parameter"),
        (["campaign", "--speeds", "0.1,0"], r"\(0, 3\] m/s"),
        (["campaign", "--postures", "elbow_up,nowhere"], "unknown posture"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(capsys, plant_files, args, message):
    args = [a.replace("{dir}", str(plant_files)) for a in args]
    code, out, err = run(capsys, *args)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    assert re.search(message, err), err


@pytest.mark.parametrize("backend", ["egl", "osmesa", "bogus"])
def test_video_renders_or_says_clearly_why_not(tmp_path, backend):
    """With a working backend the GIF is written; without one the command exits with code 2 and
    one clear line (osmesa is not installed on the development machine)."""
    video = tmp_path / "impact.gif"
    env = {k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"} | {"MUJOCO_GL": backend}
    proc = subprocess.run(
        [str(Path(sys.executable).parent / "impactqp"), "simulate", "--posture", "elbow_up", "--speed", "0.15",
         "--video", str(video)],
        capture_output=True, text=True, check=False, env=env,
    )
    assert "Traceback" not in proc.stderr
    if proc.returncode == 0:
        from PIL import Image

        with Image.open(video) as image:
            assert image.n_frames > 10
            assert np.asarray(image.convert("RGB")).std() > 1.0  # not a blank picture
    else:
        assert proc.returncode == 2
        assert len(proc.stderr.strip().splitlines()) == 1
        assert "no offscreen OpenGL backend" in proc.stderr and "MUJOCO_GL" in proc.stderr
        assert not video.exists()


# ---------------------------------------------------------------- any robot: a built-in UR5, a user's file
@pytest.fixture(scope="module")
def my_arm(tmp_path_factory):
    """A user's own arm: a copy of the UR5's description under another name in a folder of its own."""
    from impactqp.controller.model.robot_description import ROBOTS

    path = tmp_path_factory.mktemp("my_robot") / "my_arm.toml"
    path.write_text(ROBOTS["ur5"].source.read_text().replace('name = "ur5"', 'name = "my_arm"'))
    return path


@pytest.mark.parametrize("robot", ["ur5", "my_arm"])
def test_postures_and_simulate_take_any_arm(capsys, robot, my_arm, tmp_path):
    """A six-joint arm, built in or from the user's file: its postures, a simulated trial whose
    jump has one entry per joint and which hits at the asked speed, written as a valid dataset."""
    robot = robot if robot == "ur5" else str(my_arm)
    code, stdout, _ = run(capsys, "postures", "--robot", robot, "--json")
    assert code == 0 and [p["name"] for p in json.loads(stdout)] == ["elbow_up", "elbow_down", "wrist_flipped"]
    code, stdout, _ = run(capsys, "simulate", "--robot", robot, "--posture", "elbow_down", "--speed", "0.15",
                          "--out", str(tmp_path), "--json")
    assert code == 0
    report = json.loads(stdout)
    assert report["contact_speed"] == pytest.approx(0.15, rel=0.02)
    assert len(report["dq_jump"]) == 6 and all(len(jump) == 6 for jump in report["predicted"].values())
    assert not any(validate(tmp_path).values())


def test_max_speed_and_campaign_take_a_users_arm(capsys, my_arm, tmp_path):
    code, stdout, _ = run(capsys, "max-speed", "--robot", str(my_arm), "--posture", "elbow_down",
                          "--tolerance", "0.5", "--json")
    assert code == 0
    report = json.loads(stdout)
    assert report["posture"] == "elbow_down" and len(report["q_impact"]) == 6
    assert 0.0 < report["predicted_max_speed"]["robust"] <= report["predicted_max_speed"]["crb"]
    code, _, _ = run(capsys, "campaign", "--robot", str(my_arm), "--postures", "wrist_flipped", "--speeds", "0.1",
                     "--tangential", "none", "--out", str(tmp_path), "--jobs", "1")
    assert code == 0 and not any(validate(tmp_path).values())
    assert json.loads((tmp_path / "dataset.json").read_text())["robot"] == str(my_arm)
