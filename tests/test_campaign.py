"""The simulated campaign (scenarios/campaign.py): its plan, the dataset it writes, its Table I
from first principles and the figure files; a floating base's campaign, its trial runner of the
one campaign. The table itself: tests/test_campaign_table.py; the figures: tests/test_campaign_figures.py."""

import json

import numpy as np
import pytest

from conftest import G1_HEADER
from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.robot_description import PANDA, ROBOTS
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.scenarios.campaign import (
    run_stance_trials,
    PAPER_SPEEDS,
    PAPER_TANGENTIAL_SPEEDS,
    Campaign,
    CampaignPlan,
    CampaignTrials,
    check_postures,
    named_postures,
)
from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.impact import measure_impact
from impactqp.scenarios.campaign_table import held_contact_table


def test_default_plan_is_the_papers():
    specs = CampaignPlan().specs(DEFAULT_WALL)
    assert PAPER_SPEEDS == (0.08, 0.10, 0.12, 0.15, 0.18)
    assert PAPER_TANGENTIAL_SPEEDS[0] == 0.03 and PAPER_TANGENTIAL_SPEEDS[-1] == 0.12
    assert len(specs) == 3 * 5 + 10
    tangential = specs[15:]
    assert {s.posture for s in tangential} == {next(iter(PANDA.postures))}
    assert all(s.normal_speed == 0.12 for s in tangential)
    np.testing.assert_allclose([s.tangential_velocity[1] for s in tangential], PAPER_TANGENTIAL_SPEEDS)
    assert all(s.jump_model is None for s in specs)  # the tool hits at the requested speed
    assert len({s.trial_id for s in specs}) == len(specs)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"postures": ()}, "at least one posture"),
        ({"speeds": (0.1, 0.0)}, r"\[0.001, 3\] m/s"),
        ({"speeds": ()}, "at least one speed"),
    ],
)
def test_bad_plans_are_rejected(changes, message):
    with pytest.raises(ValueError, match=message):
        CampaignPlan(**changes)


def test_a_plans_postures_are_the_robots():
    with pytest.raises(ValueError, match="unknown posture 'elbow_left' for the ur5"):
        CampaignPlan(("elbow_left",)).specs(DEFAULT_WALL, RobotChoice.of("ur5"))
    specs = CampaignPlan(speeds=(0.1,), tangential_speeds=()).specs(DEFAULT_WALL, RobotChoice.of("ur5"))
    assert [s.posture for s in specs] == list(ROBOTS["ur5"].postures)


def test_a_campaign_beyond_the_free_space_is_refused_before_its_first_trial(tmp_path, monkeypatch):
    """The dataset's estimated size (``sim.generation.dataset_bytes`` of the plan's trials) with
    the margin against the free space: refused before any trial runs, nothing written."""
    import shutil

    import impactqp.controller.measured.dataset_writer as dataset_writer
    from impactqp.sim.generation import dataset_bytes

    plan = CampaignPlan(("elbow_up",), (0.1, 0.15), ())
    estimate = dataset_bytes(plan.specs(DEFAULT_WALL, RobotChoice()), PANDA)
    usage = shutil.disk_usage(tmp_path)._replace(free=int(estimate))  # less than the margin asks
    monkeypatch.setattr(dataset_writer.shutil, "disk_usage", lambda path: usage)
    monkeypatch.setattr(CampaignTrials, "results", lambda *args: pytest.fail("a trial ran"))
    with pytest.raises(BadInputError, match=f"the 2 trials need about .*{estimate / 1e6:.1f} MB estimated"):
        Campaign(plan, CampaignTrials()).run(tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign")
    plan = CampaignPlan(("elbow_left",), (0.1, 0.15), (0.05,))
    Campaign(plan, CampaignTrials()).run(out)
    return out


def test_dataset_is_valid_and_complete(campaign_dir):
    problems = validate(campaign_dir)
    assert all(not p for p in problems.values()), problems
    dataset = read_dataset(campaign_dir)
    assert [t.entry.reference_normal_speed for t in dataset.trials] == [0.1, 0.15, 0.12]
    assert dataset.trials[2].entry.reference_tangential_velocity == pytest.approx((0.0, 0.05, 0.0))
    assert all(t.entry.force_file for t in dataset.trials)


def test_table1_is_eq26_against_the_jumps_in_the_dataset(campaign_dir):
    """Recompute every entry of Table I from the written dataset alone."""
    from impactqp.controller.model.jump import JUMP_MODELS

    robot = PandaModel()
    table = json.loads((campaign_dir / "table1.json").read_text())
    dataset = read_dataset(campaign_dir)
    assert len(table["rows"]) == len(dataset.trials) == 3
    for entry, trial in zip(table["rows"], dataset.trials):
        impact = measure_impact(trial.log)
        terms = robot.terms(impact.q_pre, impact.dq_pre)
        v = terms.J @ impact.dq_pre
        for name in METHODS:
            predicted = JUMP_MODELS[name].predict(terms, DEFAULT_WALL.normal, v, 0.0).dq_jump
            expected = np.mean(np.abs(predicted - impact.dq_jump))
            assert entry["average_error"][name] == pytest.approx(expected, rel=1e-4, abs=1e-6)
    text = (campaign_dir / "table1.md").read_text()
    assert text.startswith("```text\nTable I") and "crb vs classical" in text and "all trials" in text
    assert not (campaign_dir / "table1.txt").exists()


def test_figures_are_png(campaign_dir):
    for name in ("jumps_elbow_left.png", "errors_elbow_left.png", "predicted_elbow_left.png", "tangential.png"):
        assert (campaign_dir / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_running_again_into_the_same_directory_changes_nothing(campaign_dir):
    before = (campaign_dir / "dataset.json").read_text()
    Campaign(CampaignPlan(("elbow_left",), (0.1, 0.15), (0.05,)), CampaignTrials()).run(campaign_dir)
    assert (campaign_dir / "dataset.json").read_text() == before


def test_a_campaign_of_the_fr3_with_the_franka_hand_models_what_its_manifest_says(tmp_path):
    """The FR3 hitting with the Franka Hand in the MuJoCo scene: the manifest records that robot
    and that tool, the tool's contact point touches the wall, and Table I recomputed from the
    dataset with the model of the manifest's robot and tool matches."""
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.controller.model.jump import JUMP_MODELS

    choice = RobotChoice.of("fr3", "franka_hand")
    table = Campaign(CampaignPlan(("elbow_up",), (0.1,), ()), CampaignTrials(choice)).run(tmp_path)
    dataset = read_dataset(tmp_path)
    assert dataset.header.robot == "fr3" and dataset.header.tool.as_dict() == choice.tool.as_dict()
    assert all(not p for p in validate(tmp_path).values())
    robot = dataset.header.choice.model()
    impact = measure_impact(dataset.trials[0].log)
    terms = robot.terms(impact.q_pre, impact.dq_pre)
    assert abs(DEFAULT_WALL.signed_distance(terms.contact_point)) < 2e-3  # the fingertips touch
    v = terms.J @ impact.dq_pre
    assert -DEFAULT_WALL.normal @ v == pytest.approx(0.1, rel=0.05)
    crb = JUMP_MODELS["crb"].predict(terms, DEFAULT_WALL.normal, v, 0.0).dq_jump
    assert table.rows[0].errors["crb"] == pytest.approx(np.mean(np.abs(crb - impact.dq_jump)), rel=1e-4, abs=1e-6)


@pytest.mark.parametrize("name", list(ROBOTS))
def test_a_robots_campaign_postures_are_its_description_s(name):
    """A fixed base's named postures, a floating base's stances; None: every one; an unknown
    name is bad input naming the known ones."""
    robot = ROBOTS[name]
    known = robot.stances if robot.floating else robot.postures
    assert named_postures(robot) is known and check_postures(robot, None) == tuple(known)
    assert check_postures(robot, reversed(tuple(known))) == tuple(reversed(tuple(known)))
    with pytest.raises(BadInputError, match=f"unknown posture 'nope' for the {robot.name}; known: {', '.join(known)}"):
        check_postures(robot, ("nope",))


@pytest.fixture(scope="module")
def trials():
    return run_stance_trials(RobotModel("g1"), stances=("wide",), speeds=(0.1, 0.25))


def test_one_trial_per_stance_and_speed(trials):
    assert [(t.posture, t.normal_speed) for t in trials] == [("wide", 0.1), ("wide", 0.25)]


def test_a_per_joint_armature_is_the_same_plant_as_one_number_for_every_joint():
    robot = RobotModel("g1")
    one = run_stance_trials(robot, stances=("wide",), speeds=(0.1,), armature=0.02)
    each = run_stance_trials(robot, stances=("wide",), speeds=(0.1,), armature=np.full(robot.n_joints, 0.02))
    assert one[0].errors == each[0].errors
    np.testing.assert_array_equal(one[0].measured_jump, each[0].measured_jump)


def test_the_campaign_trials_of_a_robot_with_held_contacts_are_its_stances_and_speeds():
    """The one CampaignTrials, given the G1: the plan's stances (None: every stance of the
    description) x speeds, each at the stance's posture, no tangential series; its header is the
    robot's wall dataset's."""
    robot = ROBOTS["g1"]
    trials = CampaignTrials(RobotChoice(robot))
    tasks = trials.tasks(CampaignPlan(None, (0.1, 0.2), ()))
    assert [(s.posture, s.normal_speed) for s in tasks] == [(s, v) for s in robot.stances for v in (0.1, 0.2)]
    model = RobotModel(robot)
    for spec in tasks:
        np.testing.assert_array_equal(spec.q_contact, stance_posture(model, robot.stances[spec.posture]))
    assert trials.header.to_dict() == G1_HEADER.to_dict()
    with pytest.raises(BadInputError, match="unknown posture 'elbow_up' for the g1"):
        trials.tasks(CampaignPlan(("elbow_up",), (0.1,), ()))
    with pytest.raises(BadInputError, match="no tangential series"):
        trials.tasks(CampaignPlan(("wide",), (0.1,), (0.05,)))


def test_the_campaign_trials_of_a_robot_with_held_contacts_are_its_standing_trials(trials):
    """What the one CampaignTrials runs for the G1 is the scripted standing trial of each stance
    and speed, its table the floating base's."""
    campaign = CampaignTrials(RobotChoice(ROBOTS["g1"]))
    results = list(campaign.results(campaign.tasks(CampaignPlan(("wide",), (0.1, 0.25), ())), 1))
    for result, trial in zip(results, trials, strict=True):
        assert result.errors == trial.errors and result.failures == trial.failures
        np.testing.assert_array_equal(result.measured_jump, trial.measured_jump)
    assert campaign.table(results).layout == held_contact_table("g1")
