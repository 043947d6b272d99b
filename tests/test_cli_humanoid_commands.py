"""``--robot g1`` on predict, simulate and campaign (scenarios/cli/humanoid_commands.py), and its
max-speed options that do not apply."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT

from conftest import g1_model, file_digests


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_predict_g1_json(capsys):
    code, out, _ = run(capsys, "predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0",
                       "--speed", "0.3", "--json")
    assert code == 0
    report = json.loads(out)
    assert {"q", "contact_point", "normal", "pre_impact_velocity", "restitution", "cond_M", "methods"} <= set(report)
    assert set(report["methods"]) == {"classical", "gm", "crb"}
    for entry in report["methods"].values():
        assert len(entry["dq_jump"]) == g1_model().model.nv and len(entry["feet_impulse"]) == 12
        assert np.asarray(entry["impulse"]) @ [-1.0, 0.0, 0.0] > 0.0


def test_predict_g1_takes_a_configuration(capsys):
    q = ",".join(f"{x:g}" for x in pin.neutral(g1_model().model))  # the base at the origin, upright
    code, out, _ = run(capsys, "predict", "--robot", "g1", "--q", q, "--normal", "-1,0,0", "--speed", "0.2",
                       "--method", "gm", "--json")
    assert code == 0 and list(json.loads(out)["methods"]) == ["gm"]


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


@pytest.mark.parametrize("args", [
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--wall-point", "1,0,0"),
    ("max-speed", "--robot", "g1", "--posture", "parallel", "--jump-model", "gm"),
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--jump-model", "gm"),
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--controller", "qp",
     "--jump-model", "robust"),
    ("simulate", "--posture", "elbow_right", "--speed", "0.1", "--controller", "qp"),
    ("predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0", "--speed", "0.2", "--tool", "pad"),
    ("campaign", "--robot", "g1", "--postures", "kneeling"),
    ("postures", "--robot", "g1"),
])
def test_what_does_not_apply_to_the_g1_is_one_line_of_bad_input(capsys, args):
    code, out, err = run(capsys, *args)
    assert code == EXIT_BAD_INPUT
    assert err.count("\n") == 1 and err.startswith("impactqp: error:")


def test_stances_are_the_g1_postures():
    assert {"parallel", "wide", "staggered", "close", "far"} <= set(STANCES)


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
