"""The humanoid campaign and its table (scenarios/humanoid_campaign.py)."""

import numpy as np
import pytest

from impactqp.controller.model.floating_base import FloatingBaseModel
from impactqp.scenarios.humanoid_campaign import PREDICTORS, campaign_table, crb_reduction, mean_errors, run_campaign


@pytest.fixture(scope="module")
def trials():
    return run_campaign(FloatingBaseModel(), stances=("wide",), speeds=(0.1, 0.25))


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
    robot = FloatingBaseModel()
    one = run_campaign(robot, stances=("wide",), speeds=(0.1,), armature=0.02)
    each = run_campaign(robot, stances=("wide",), speeds=(0.1,), armature=np.full(robot.n_joints, 0.02))
    assert one[0].errors == each[0].errors
    np.testing.assert_array_equal(one[0].measured_jump, each[0].measured_jump)
