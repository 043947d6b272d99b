"""Table I of every robot (scenarios/campaign_table.py): CRB's reduction, the means over the
trials, an arm's aligned text and a robot with held contacts' Markdown and JSON, from the rows."""

import json

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import PANDA, ROBOTS
from impactqp.scenarios.campaign import run_stance_trials
from impactqp.scenarios.campaign_table import (
    ARM_TABLE,
    HELD_CONTACT_PREDICTORS,
    Table1,
    TableRow,
    crb_reduction,
    held_contact_table,
    table_layout,
)


def row(classical, crb):
    errors = {m: 1.0 for m in METHODS} | {"classical": classical, "crb": crb}
    return TableRow("t", "p", 0.1, 0.0, 0.1, errors, np.zeros(JOINTS), {m: np.zeros(JOINTS) for m in METHODS})


def test_crb_reduction_is_relative_to_classical():
    assert row(0.5, 0.1).crb_reduction == pytest.approx(80.0)
    table = Table1([row(0.5, 0.1), row(0.3, 0.3)])
    assert table.mean_errors()["classical"] == pytest.approx(0.4)
    assert table.mean_crb_reduction() == pytest.approx(50.0)


def test_crb_reduction_sign():
    assert crb_reduction({"crb": 0.2, "classical": 1.0}) == pytest.approx(80.0)
    assert crb_reduction({"crb": 2.0, "classical": 1.0}) == pytest.approx(-100.0)


def test_a_robots_layout_is_its_descriptions():
    """An arm's table is aligned text with figures, a robot with held contacts' Markdown naming it."""
    assert table_layout(PANDA) is ARM_TABLE and ARM_TABLE.figures and not ARM_TABLE.markdown
    g1 = table_layout(ROBOTS["g1"])
    assert g1 == held_contact_table("g1") and not g1.figures and g1.markdown and g1.robot == "g1"
    assert g1.methods == HELD_CONTACT_METHODS and g1.shown == (*HELD_CONTACT_METHODS, "momentum")


def test_an_arms_text_has_a_line_per_trial_and_the_mean():
    table = Table1([row(0.5, 0.1), row(0.3, 0.3)])
    lines = table.text().splitlines()
    assert len(lines) == 2 + 2 + 1 and lines[-1].startswith("all trials")
    assert lines[-1].endswith(f"{table.mean_crb_reduction():.1f} %")
    assert list(table.files()) == ["table1.json", "table1.md"]
    assert table.files()["table1.md"] == f"```text\n{table.text()}\n```\n"  # the aligned text, fenced
    data = json.loads(table.files()["table1.json"])
    assert "robot" not in data and [r["trial"] for r in data["rows"]] == ["t", "t"]
    assert data["methods"] == list(METHODS)


@pytest.fixture(scope="module")
def trials():
    return run_stance_trials(RobotModel("g1"), stances=("wide",), speeds=(0.1, 0.25))


@pytest.fixture(scope="module")
def table(trials):
    return Table1.of(ROBOTS["g1"], trials)


def test_mean_errors_average_the_trials(trials, table):
    errors = table.mean_errors(HELD_CONTACT_PREDICTORS)
    for m in HELD_CONTACT_PREDICTORS:
        assert errors[m] == pytest.approx(np.mean([t.errors[m] for t in trials]))


def test_rows_are_the_trials(trials, table):
    """Each row's errors are its trial's (26), its per-joint errors |predicted - measured| over the joints."""
    joints = slice(RobotModel("g1").base_nv, None)
    for r, t in zip(table.rows, trials, strict=True):
        assert r.errors == t.errors and r.trial_id == t.trial_id
        for m, dv in t.predicted.items():
            assert r.joint_errors[m].mean() == pytest.approx(t.errors[m], rel=1e-12)
            np.testing.assert_array_equal(r.joint_errors[m], np.abs(dv[joints] - t.measured_jump[joints]))


def test_markdown_has_a_row_per_trial_and_the_mean(trials, table):
    text = table.text()
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    assert len(rows) == 1 + len(trials) + 1
    assert all(line.count("|") == rows[0].count("|") for line in rows)
    assert f"{crb_reduction(table.mean_errors(HELD_CONTACT_PREDICTORS)):+.1f} %" in text


def test_the_table_json_rows_are_the_trials(trials, table):
    data = json.loads(table.files()["table1.json"])
    assert data == json.loads(json.dumps(table.to_json())) and data["robot"] == "g1"
    assert [r["posture"] for r in data["rows"]] == [t.posture for t in trials]
    assert [r["trial"] for r in data["rows"]] == list(range(len(trials)))
    for row_, trial in zip(data["rows"], trials):
        reduction = 100 * (1 - trial.errors["crb"] / trial.errors["classical"])
        assert row_["crb_reduction_percent"] == pytest.approx(reduction)
        assert row_["foot_slip"] == trial.held.foot_slip and "predicted" not in row_
    assert set(data["mean_average_error"]) == set(HELD_CONTACT_METHODS)
    assert list(table.files()) == ["table1.json", "table1.md"]  # the arm's two names
    assert table.files()["table1.md"] == table.text() + "\n" and table.write_figures(None) == []
