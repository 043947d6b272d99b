"""The robust friction rows against MuJoCo at the QP's own highest speed
(``scenarios.oblique_campaign``, ``impactqp oblique --qp-speed``): the grid's trials, the two
controllers of a trial, the command end to end (its bad input: ``tests/test_oblique.py``)."""

import json

import numpy as np
import pytest

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.friction_pyramid import FrictionRows
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.max_speed import Setting
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.scenarios.cli import main
from impactqp.scenarios.oblique_campaign import QP_SPEED_GRIDS, QpSpeedGrid, qp_speed_grid_named, summary

NORMAL = DEFAULT_WALL.normal


def test_the_grid_slides_at_its_ratios_of_the_robust_rows_closed_form():
    """v_t = r v_ref, v_ref the robust rows' closed form at v_t = 0 (every predictor of the rows)."""
    choice = RobotChoice.of("panda")
    grid = QpSpeedGrid(ratios=(0.0, 0.5, 1.0), frictions=(0.2,), postures=1, jump_model="robust")
    trials = grid.trials(choice)
    robot = choice.model()
    terms = robot.terms(choice.posture(trials[0].posture).q)
    reference = min(
        frictional_max_speed(robot, terms, NORMAL, np.zeros(3), Setting(m), FrictionRows(0.2)).max_speed.speed
        for m in ("classical", "gm", "crb")
    )
    assert [t.ratio for t in trials] == [0.0, 0.5, 1.0]
    assert [t.tangential_speed for t in trials] == pytest.approx([0.0, 0.5 * reference, reference], rel=1e-12)
    assert {t.friction for t in trials} == {0.2}


def test_the_summary_counts_the_broken_limits_of_each_controller():
    def run(ratio, torque, speed):
        return {"max_velocity_ratio": ratio, "max_torque_ratio": torque, "violated": ratio > 1 or torque > 1,
                "contact_speed": speed}

    rows = [{"runs": {"robust": run(0.9, 0.5, 0.1), "normal": run(1.2, 0.4, 0.3)}},
            {"runs": {"robust": run(0.8, 0.7, 0.2), "normal": run(0.7, 1.1, 0.4)}},
            {"runs": {"robust": run(0.5, 0.2, 0.3), "normal": run(0.6, 0.3, 0.5)}}]
    s = summary(rows)
    assert s["robust"] == {"trials": 3, "violated": 0, "max_velocity_ratio": 0.9, "max_torque_ratio": 0.7,
                           "median_contact_speed": 0.2}
    assert s["normal"]["violated"] == 2 and s["normal"]["max_velocity_ratio"] == 1.2


def test_the_small_campaign_runs_end_to_end_through_the_command(tmp_path, capsys):
    """Both controllers hit the wall at the QP's own speed, the robust rows' no faster than the
    normal-only rows' (they add rows), and the robust rows break no joint velocity limit."""
    out = tmp_path / "oblique"
    assert main(["oblique", "--qp-speed", "--grid", "small", "--out", str(out)]) == 0
    report = json.loads((out / "qp-speed.json").read_text())
    assert report["robot"] == "panda" and report["jump_model"] == "classical"
    (row,) = report["rows"]
    robust, normal = row["runs"]["robust"], row["runs"]["normal"]
    assert 0.0 < robust["contact_speed"] <= normal["contact_speed"]
    assert robust["max_velocity_ratio"] <= 1.0 and not robust["violated"]
    assert robust["pre_tangential_speed"] == pytest.approx(row["tangential_speed"], rel=0.05)
    assert report["summary"] == summary(report["rows"])
    text = (out / "qp-speed.md").read_text()
    assert text.startswith("# Oblique impacts at the QP's own highest speed: the panda") and text in capsys.readouterr().out


def test_the_named_grids_keep_their_trials_and_take_the_jump_model():
    grid = qp_speed_grid_named("full", "crb")
    assert grid.jump_model == "crb" and grid.ratios == QP_SPEED_GRIDS["full"].ratios
    assert len(grid.trials(RobotChoice.of("fr3", "franka_hand"))) == 30
