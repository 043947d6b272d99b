"""`impactqp simulate` and `campaign` (and the wall and plant options `max-speed` shares): JSON
contracts, dataset output, video, and one-line errors with exit code 2, for the arms and for the
standing G1 (``--robot g1``)."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_checks import one_line_bad_input
from conftest import JOINTS, file_digests, g1_model
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT
from impactqp.controller.measured.dataset import read_dataset
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


def test_simulate_with_friction_puts_the_friction_rows_in_the_qp_and_mu_on_the_wall(capsys, monkeypatch):
    from impactqp.scenarios import trial as trial_module
    from impactqp.sim import trial_sources

    seen = {}
    build_scene, build_controller = trial_module.build_scene, trial_sources.build_controller

    def scene(surface, *args, **kwargs):
        seen["wall"] = surface.friction
        return build_scene(surface, *args, **kwargs)

    def controller(config, *args, **kwargs):
        built = build_controller(config, *args, **kwargs)
        seen["rows"] = {c.name: c.rows for c in built.constraints}
        seen["friction"] = config.impact.friction_setting()
        return built

    monkeypatch.setattr(trial_module, "build_scene", scene)
    monkeypatch.setattr(trial_sources, "build_controller", controller)
    code, stdout, _ = run(
        capsys, "simulate", "--posture", "elbow_up", "--speed", "0.2", "--tangential", "0,0.05,0", "--friction", "0.3",
        "--json",
    )
    assert code == 0 and json.loads(stdout)["jump_model"] == "crb"
    assert seen["wall"] == 0.3 and seen["friction"].friction == 0.3 and seen["friction"].count == 4
    assert seen["rows"]["post_impact_velocity[crb]"] == seen["rows"]["impulsive_torque[crb]"] == JOINTS * 5


def test_campaign_json(capsys, tmp_path):
    code, stdout, _ = run(
        capsys, "campaign", "--postures", "elbow_up", "--speeds", "0.1", "--tangential", "none",
        "--out", str(tmp_path), "--json",
    )
    assert code == 0
    table = json.loads(stdout)
    assert len(table["rows"]) == 1 and table["rows"][0]["posture"] == "elbow_up"
    assert json.loads((tmp_path / "table1.json").read_text()) == table  # the G1's two names (below)
    assert (tmp_path / "table1.md").read_text().startswith("```text\n") and not (tmp_path / "table1.txt").exists()


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
        (["simulate", "--posture", "elbow_up", "--speed", "0"], r"\[0.001, 3\] m/s"),
        (["simulate", "--posture", "elbow_up", "--speed", "-0.1"], r"\[0.001, 3\] m/s"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/unknown.json"], "unknown plant parameter"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/shape.json"], f"armature must be {JOINTS} numbers"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{dir}/missing.json"], "does not exist"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1.6,0,0"], "out of reach"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-normal", "0,0,0"], "zero"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1,2"], "3 values"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--tangential", "0.1,0,0"], "orthogonal"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--jump-model", "magic"], "magic"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--video", "x.mp4"], "GIF"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--figure", "x.jpg"], r"--figure writes a figure"),
        (["max-speed", "--posture", "nowhere"], "unknown posture"),
        (["max-speed", "--posture", "elbow_up", "--wall-point", "1.6,0,0"], "out of reach"),
        (["max-speed", "--posture", "elbow_up", "--restitution", "1.5"], r"\[0, 1\]"),
        (["max-speed", "--posture", "elbow_up", "--impact-duration", "0"], "one control period"),
        (["max-speed", "--posture", "elbow_up", "--impact-duration", "1e-9"], "one control period"),
        (["simulate", "--posture", "elbow_up", "--speed", "1e9"], r"\[0.001, 3\] m/s"),
        (["campaign", "--speeds", "50"], r"\[0.001, 3\] m/s"),
        (["max-speed", "--posture", "elbow_up", "--jobs", "0"], "--jobs"),
        (["max-speed", "--posture", "elbow_up", "--plant", "{dir}/unknown.json"], "unknown plant parameter"),
        (["campaign", "--speeds", "0.1,0"], r"\[0.001, 3\] m/s"),
        (["campaign", "--postures", "elbow_up,nowhere"], "unknown posture"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--friction", "2.5"], r"--friction: .*\[0, 2\]"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--friction", "0.3", "--no-jump-constraint"], "--no-jump-constraint"),
        (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--friction", "0.3", "--jump-model", "classical_normal"],
         "classical_normal"),
        (["simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.1", "--friction", "0.3"], "give --controller qp"),
        (["simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.1", "--controller", "qp", "--friction", "3"],
         r"--friction: .*\[0, 2\]"),
        (["max-speed", "--posture", "elbow_up", "--friction", "-1"], r"--friction: .*\[0, 2\]"),
        (["max-speed", "--posture", "elbow_up", "--tangential", "0,0.1,0"], "give --friction too"),
        (["max-speed", "--posture", "elbow_up", "--friction", "0.3", "--tangential", "0.1,0,0"], "orthogonal"),
        (["max-speed", "--posture", "elbow_up", "--friction", "0.3", "--jobs", "2"], "--jobs"),
        (["max-speed", "--robot", "g1", "--posture", "parallel", "--tangential", "0,0.1,0"], "give --friction too"),
        (["max-speed", "--robot", "g1", "--posture", "parallel", "--friction", "0.3", "--tangential", "0.1,0,0"],
         "orthogonal"),
        (["max-speed", "--robot", "g1", "--posture", "parallel", "--friction", "0.3", "--jobs", "2"], "--jobs"),
        (["max-speed", "--robot", "g1", "--posture", "parallel", "--friction", "0.3", "--controller", "qp",
          "--tangential", "0,0.1,0"], "--tangential does not apply"),
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


@pytest.mark.parametrize("robot", [["--posture", "elbow_up"], ["--robot", "g1", "--posture", "parallel"]])
def test_view_without_a_display_is_refused_before_simulating(capsys, monkeypatch, robot):
    from impactqp.scenarios.trial import TrialRunner

    def simulated(*args, **kwargs):
        raise AssertionError("a trial was simulated before --view was refused")

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(TrialRunner, "run", simulated)
    code, out, err = run(capsys, "simulate", *robot, "--speed", "0.1", "--view")
    assert code == EXIT_BAD_INPUT and out == ""
    assert err.count("\n") == 1 and "--view" in err and "no display" in err


def test_simulate_writes_the_velocity_figure(capsys, tmp_path):
    path = tmp_path / "velocities.png"
    code, _, err = run(capsys, "simulate", "--posture", "elbow_up", "--speed", "0.1", "--figure", str(path))
    assert code == 0, err
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


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
    # the replay backend plays the user's arm's dataset: its model comes from the robot file
    code, stdout, err = run(capsys, "run", "--backend", "replay", "--dataset", str(tmp_path), "--log", str(tmp_path / "replayed"), "--json")
    assert code == 0, err
    assert json.loads(stdout)["cycles"] > 0


def test_simulate_g1_json(capsys):
    code, out, _ = run(capsys, "simulate", "--robot", "g1", "--posture", "close", "--speed", "0.2", "--json")
    assert code == 0
    report = json.loads(out)
    assert {"contact_speed", "impulse", "dq_jump", "predicted", "errors", "foot_slip", "foot_lift", "fell",
            "max_velocity_ratio", "first_failure", "violated"} <= set(report)
    assert len(report["dq_jump"]) == g1_model().model.nv and report["violated"] is False


def test_simulate_g1_driven_by_the_whole_body_qp(capsys):
    code, out, _ = run(capsys, "simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2",
                       "--controller", "qp", "--jump-model", "gm", "--json")
    assert code == 0
    report = json.loads(out)
    assert report["controller"] == "qp" and report["jump_model"] == "gm" and report["cycles_not_ok"] >= 0
    assert {"contact_speed", "dq_jump", "errors", "fell", "first_failure", "violated"} <= set(report)
    code, text, _ = run(capsys, "simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2",
                        "--controller", "qp")
    assert code == 0 and "whole-body QP (crb)" in text


def test_simulate_g1_with_the_friction_rows_of_the_whole_body_qp(capsys):
    """``--friction`` with the whole-body QP: its robust friction rows of that mu, on a wall of that mu."""
    code, out, _ = run(capsys, "simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2",
                       "--controller", "qp", "--friction", "0.3", "--json")
    assert code == 0
    report = json.loads(out)
    assert report["controller"] == "qp" and report["friction"] == 0.3 and report["cycles_not_ok"] >= 0
    assert report["contact_speed"] > 0.0


def test_simulate_g1_with_zero_friction_gives_the_wall_no_friction(capsys, monkeypatch):
    """``--friction 0`` with the whole-body QP: no friction rows and a frictionless wall, as an
    arm's (the scene the trial runs on, read from MuJoCo's hand/wall pair)."""
    from impactqp.sim import runner

    seen = []
    build = runner.build_humanoid_scene

    def scene(*args, **kwargs):
        built = build(*args, **kwargs)
        model = built.model
        seen.extend(float(model.pair_friction[i][0]) for i in range(model.npair)
                    if {int(model.pair_geom1[i]), int(model.pair_geom2[i])} == {built.hand_geom, built.wall_geom})
        return built

    monkeypatch.setattr(runner, "build_humanoid_scene", scene)
    code, out, _ = run(capsys, "simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2",
                       "--controller", "qp", "--friction", "0", "--json")
    assert code == 0 and json.loads(out)["friction"] == 0.0
    assert seen == [0.0]


def test_campaign_g1_json_and_files(capsys, tmp_path):
    code, out, _ = run(capsys, "campaign", "--robot", "g1", "--postures", "parallel", "--speeds", "0.2",
                       "--out", str(tmp_path), "--json")
    assert code == 0
    table = json.loads(out)
    assert {"methods", "rows", "mean_average_error", "mean_crb_reduction_percent"} <= set(table)
    assert len(table["rows"]) == 1 and table["rows"][0]["posture"] == "parallel"
    assert json.loads((tmp_path / "table1.json").read_text()) == table
    assert (tmp_path / "table1.md").read_text().startswith("| stance")
    # the campaign's trials, as a G1 dataset beside the table
    manifest = json.loads((tmp_path / "dataset.json").read_text())
    assert manifest["robot"] == "g1" and [t["posture"] for t in manifest["trials"]] == ["parallel"]
    assert main(["dataset", "validate", str(tmp_path)]) == 0


def test_simulate_g1_out_adds_the_trial_to_a_g1_dataset(capsys, tmp_path):
    args = ("simulate", "--robot", "g1", "--posture", "close", "--speed", "0.2", "--out", str(tmp_path))
    code, out, _ = run(capsys, *args)
    assert code == 0 and f"trial close_vn200_scripted written to {tmp_path}" in out
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    code, out, _ = run(capsys, *args, "--json")  # the same trial again: nothing changes, the JSON alone
    assert code == 0 and "dq_jump" in json.loads(out)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    data = read_dataset(tmp_path)
    assert data.header.robot == "g1" and [t.entry.id for t in data.trials] == ["close_vn200_scripted"]
    assert data.trials[0].log.q.shape[1] == g1_model().n_joints and data.trials[0].log.has_force
    code, out, _ = run(capsys, "dataset", "validate", str(tmp_path))
    assert code == 0 and "0 problem(s) in 1 trial(s)" in out


@pytest.mark.parametrize("command", ["simulate", "campaign"])
def test_a_g1_trial_is_never_added_to_an_arm_dataset(capsys, dataset, command):
    """Refused before any trial is simulated: one line of bad input, the arm's files untouched."""
    before = file_digests(dataset)
    speed = ("--speed", "0.2") if command == "simulate" else ("--speeds", "0.2")
    code, _, err = run(capsys, command, "--robot", "g1", "--posture" + ("s" if command == "campaign" else ""),
                       "parallel", *speed, "--out", str(dataset))
    assert code == EXIT_BAD_INPUT and err.count("\n") == 1 and "another header" in err
    assert file_digests(dataset) == before


def test_simulate_g1_video_is_a_gif(tmp_path):
    """As a user runs it (a fresh process picks MuJoCo's OpenGL backend, egl by default): a GIF
    of the trial that is not a blank picture."""
    from PIL import Image

    path = tmp_path / "g1.gif"
    env = {k: v for k, v in os.environ.items() if k not in ("PYOPENGL_PLATFORM", "MUJOCO_GL")}
    proc = subprocess.run(
        [str(Path(sys.executable).parent / "impactqp"), "simulate", "--robot", "g1", "--posture", "parallel",
         "--speed", "0.3", "--video", str(path)],
        capture_output=True, text=True, check=False, env=env,
    )
    assert proc.returncode == 0, proc.stderr
    with Image.open(path) as image:
        assert image.format == "GIF" and image.n_frames > 10
        assert np.asarray(image.convert("RGB")).std() > 1.0


def test_simulate_on_the_identified_panda_meets_its_friction(capsys):
    """``--plant identified_panda``, a built-in plant by name: the same approach as on the nominal
    plant, its joints now braked by dry friction that the slow servo (5 rad/s) does not fully
    make up for: the tool reaches the wall slower, and the jump differs."""
    results = {}
    for plant in (None, "identified_panda"):
        args = ["simulate", "--posture", "elbow_left", "--speed", "0.1", "--json"] + (["--plant", plant] if plant else [])
        code, stdout, err = run(capsys, *args)
        assert code == 0, err
        results[plant] = json.loads(stdout)
    assert results["identified_panda"]["contact_speed"] < results[None]["contact_speed"]
    assert results["identified_panda"]["dq_jump"] != results[None]["dq_jump"]


def test_a_campaign_beyond_the_trial_limit_is_refused_with_its_count_before_any_work(tmp_path, capsys):
    code, out, err = run(capsys, "campaign", "--out", str(tmp_path / "c"), "--postures", "elbow_up", "--speeds", "0.1,0.12", "--tangential", "none", "--max-trials", "1")
    one_line_bad_input(code, out, err, "the campaign has 2 trials (1 posture x 2 speeds + 0 tangential), more than the limit of 1")
    assert not (tmp_path / "c").exists()
    code, out, err = run(capsys, "campaign", "--out", str(tmp_path / "c"), "--speeds", "0.1", "--max-trials", "0")
    one_line_bad_input(code, out, err, "--max-trials must be a whole number >= 1")
