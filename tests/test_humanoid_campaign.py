"""The humanoid campaign, its trial runner of the one campaign and its table (scenarios/humanoid_campaign.py)."""

import json

import numpy as np
import pytest

from conftest import G1_HEADER

from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.campaign import CampaignPlan
from impactqp.scenarios.humanoid_campaign import (
    PREDICTORS,
    FloatingBaseTable,
    FloatingBaseTrials,
    campaign_table,
    crb_reduction,
    mean_errors,
    run_campaign,
)


@pytest.fixture(scope="module")
def trials():
    return run_campaign(RobotModel("g1"), stances=("wide",), speeds=(0.1, 0.25))


def test_one_trial_per_stance_and_speed(trials):
    assert [(t.stance, t.speed) for t in trials] == [("wide", 0.1), ("wide", 0.25)]


def test_mean_errors_average_the_trials(trials):
    errors = mean_errors(trials)
    for m in PREDICTORS:
        assert errors[m] == pytest.approx(np.mean([t.errors[m] for t in trials]))


def test_table_has_a_row_per_trial_and_the_mean(trials):
    table = campaign_table(trials)
    rows = [line for line in table.splitlines() if line.startswith("| ")]
    assert len(rows) == 1 + len(trials) + 1
    assert f"{crb_reduction(mean_errors(trials)):+.1f} %" in table


def test_crb_reduction_sign():
    assert crb_reduction({"crb": 0.2, "classical": 1.0}) == pytest.approx(80.0)
    assert crb_reduction({"crb": 2.0, "classical": 1.0}) == pytest.approx(-100.0)


def test_a_per_joint_armature_is_the_same_plant_as_one_number_for_every_joint():
    robot = RobotModel("g1")
    one = run_campaign(robot, stances=("wide",), speeds=(0.1,), armature=0.02)
    each = run_campaign(robot, stances=("wide",), speeds=(0.1,), armature=np.full(robot.n_joints, 0.02))
    assert one[0].errors == each[0].errors
    np.testing.assert_array_equal(one[0].measured_jump, each[0].measured_jump)


def test_the_campaign_runner_plans_the_stances_and_speeds():
    """FloatingBaseTrials: the plan's stances (None: every stance of the description) x speeds, no
    tangential series; its header is the robot's wall dataset's."""
    robot = ROBOTS["g1"]
    trials = FloatingBaseTrials(robot)
    tasks = trials.tasks(CampaignPlan(None, (0.1, 0.2), ()))
    assert [(s, v) for _, s, v in tasks] == [(s, v) for s in robot.stances for v in (0.1, 0.2)]
    assert all(r is robot for r, _, _ in tasks)
    assert trials.header.to_dict() == G1_HEADER.to_dict()
    with pytest.raises(BadInputError, match="unknown posture 'elbow_up' for the g1"):
        trials.tasks(CampaignPlan(("elbow_up",), (0.1,), ()))
    with pytest.raises(BadInputError, match="no tangential series"):
        trials.tasks(CampaignPlan(("wide",), (0.1,), (0.05,)))


def test_the_table_json_rows_are_the_trials(trials):
    table = FloatingBaseTable("g1", trials)
    data = json.loads(table.files()["table1.json"])
    assert data == json.loads(json.dumps(table.to_json())) and data["robot"] == "g1"
    assert [r["posture"] for r in data["rows"]] == [t.stance for t in trials]
    for row, trial in zip(data["rows"], trials):
        assert row["crb_reduction_percent"] == pytest.approx(100 * (1 - trial.errors["crb"] / trial.errors["classical"]))
    assert set(data["mean_average_error"]) == set(METHODS)
    assert table.files()["table1.md"] == campaign_table(trials) + "\n" and table.write_figures(None) == []
