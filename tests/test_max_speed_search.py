"""Maximum feasible speed: the parallel bisection (the arm's and the G1's) on a known threshold,
a G1 stance the description does not have, and one real search in closed loop (the QP reaches the closed-form maximum; the bracket of the simulation is sound)."""

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cli_checks import one_line_bad_input, run
from conftest import JOINTS, g1_model
from test_robot_description import _user_arm
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.max_speed import Setting, approach_direction, closed_form_max_speed
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.robot import RobotModel
from impactqp.sim.runner import NORMAL
from impactqp.sim.trial_sources import QpCommand
from impactqp.scenarios.max_speed_search import (
    STANCE_HIGHEST_SPEED,
    STANCE_LOWEST_SPEED,
    STANCE_MIN_TOLERANCE,
    Evaluation,
    MaxSpeedSearch,
    QpSetting,
    SpeedBisection,
    SpeedChecks,
    StancePlant,
    approach_velocity_limit,
    search_stance,
)


def oracle(threshold):
    return lambda v: Evaluation(v, v, v / threshold, 0.0, v > threshold)


@pytest.mark.parametrize("jobs", [1, 2, 3])
def test_bisection_converges_on_a_known_threshold(jobs):
    feasible_until = oracle(0.237)
    bisection = SpeedBisection(0.02, 1.0, 0.005)
    rounds = 0
    while not bisection.done:
        speeds = bisection.next_speeds(jobs)
        assert all(bisection.lo < v < bisection.hi for v in speeds)
        bisection.update([feasible_until(v) for v in speeds])
        rounds += 1
    assert bisection.lo <= 0.237 < bisection.hi
    assert bisection.hi - bisection.lo <= 0.005
    # (jobs + 1)-section: the bracket shrinks by jobs + 1 per round
    assert rounds <= int(np.ceil(np.log(0.98 / 0.005) / np.log(jobs + 1)))


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 4.0), st.floats(0.002, 0.2), st.integers(1, 3))
def test_search_brackets_the_threshold_of_a_monotone_feasibility(threshold, tolerance, jobs):
    """The search of both plants (the G1's bracket): 0 when lo fails, hi when hi holds, else
    lo <= threshold < lo + tolerance, every trial kept."""
    calls = []

    def evaluate(speeds):
        calls.extend(speeds)
        return [Evaluation(v, v, 0.5, 0.0, v > threshold) for v in speeds]

    bisection = SpeedBisection(STANCE_LOWEST_SPEED, STANCE_HIGHEST_SPEED, tolerance, STANCE_MIN_TOLERANCE)
    best = bisection.search(evaluate, jobs)
    assert [e.reference_speed for e in bisection.evaluations] == calls
    if threshold < STANCE_LOWEST_SPEED:
        assert best == 0.0
    elif threshold >= STANCE_HIGHEST_SPEED:
        assert best == STANCE_HIGHEST_SPEED
    else:
        assert best <= threshold < best + tolerance


def test_search_uses_the_ends_already_evaluated():
    calls = []

    def evaluate(speeds):
        calls.extend(speeds)
        return [oracle(0.3)(v) for v in speeds]

    bisection = SpeedBisection(0.02, 1.0, 0.005)
    assert bisection.search(evaluate, 1, [oracle(0.3)(0.02), oracle(0.3)(1.0)]) == bisection.lo
    assert 0.02 not in calls and 1.0 not in calls and len(bisection.evaluations) == len(calls) + 2


def test_approach_velocity_limit_puts_one_joint_at_its_limit(robot):
    q = PANDA.postures["elbow_left"].q
    v_a = approach_velocity_limit(robot, q, DEFAULT_WALL.normal)
    ratio = np.abs(v_a * approach_direction(robot, robot.terms(q), DEFAULT_WALL.normal)) / robot.dq_max
    assert ratio.max() == pytest.approx(1.0)


@pytest.fixture(scope="module")
def report():
    return MaxSpeedSearch(PANDA.postures["elbow_up"], DEFAULT_WALL, setting=QpSetting("crb"), tolerance=0.02, jobs=2).run()


def test_qp_reaches_the_closed_form_maximum_speed(report, robot):
    data = report.to_json()
    terms = robot.terms(np.array(data["q_impact"]))
    # the posture of the QP run's impact: its tool tip is where the named posture's is
    named_tip = robot.contact_point(PANDA.postures["elbow_up"].q)
    assert np.linalg.norm(terms.contact_point - named_tip) < 0.01
    for name in ("classical", "gm", "crb"):
        expected = closed_form_max_speed(robot, terms, DEFAULT_WALL.normal, Setting(name))
        assert data["predicted_max_speed"][name] == pytest.approx(expected.speed)
        assert data["binding"][name] == {"criterion": expected.criterion, "joint": expected.joint}
    assert data["qp_limited_speed"] == pytest.approx(data["predicted_max_speed"]["crb"], rel=0.05)
    # the QP kept the impact inside what the crb model allows, which the simulation confirms
    assert data["qp_max_velocity_ratio"] < 1.0


def test_bisection_brackets_are_consistent(report):
    evaluations = report.evaluations
    speeds = [e.reference_speed for e in evaluations]
    assert speeds == sorted(speeds)
    best = report.simulated_max_speed
    below = [e for e in evaluations if e.reference_speed <= best]
    above = [e for e in evaluations if e.reference_speed > best]
    assert below and above
    assert not any(e.violated for e in below)
    assert above[0].violated
    assert above[0].reference_speed - best <= 0.02 + 1e-12
    for e in evaluations:
        assert e.violated == (e.max_velocity_ratio > 1.0 or e.max_torque_ratio > 1.0)
        assert e.contact_speed == pytest.approx(e.reference_speed, rel=0.03)


def test_report_json_keys(report):
    data = report.to_json()
    assert {
        "posture", "q_impact", "normal", "predicted_max_speed", "binding", "qp_limited_speed",
        "qp_max_velocity_ratio", "qp_max_torque_ratio", "simulated_max_speed", "evaluations",
    } <= set(data)
    assert len(data["q_impact"]) == JOINTS and len(data["normal"]) == 3
    assert set(data["evaluations"][0]) == {
        "reference_speed", "contact_speed", "max_velocity_ratio", "max_torque_ratio", "violated",
    }


def test_bad_search_settings_are_rejected():
    with pytest.raises(ValueError, match="unknown jump model"):
        QpSetting("magic")
    with pytest.raises(ValueError, match="tolerance"):
        SpeedBisection(0.02, 1.0, 0.0)
    with pytest.raises(BadInputError, match="tolerance"):
        SpeedBisection(STANCE_LOWEST_SPEED, STANCE_HIGHEST_SPEED, 0.5 * STANCE_MIN_TOLERANCE, STANCE_MIN_TOLERANCE)


def test_a_max_speed_search_of_the_fr3_with_the_franka_hand_reaches_its_closed_form():
    """The FR3 hitting with the Franka Hand in the MuJoCo scene: the QP-limited run settles at
    the closed-form crb speed of that robot and tool at its impact posture, and the bisection
    brackets the simulated maximum."""
    from impactqp.controller.model.choice import RobotChoice

    choice = RobotChoice.of("fr3", "franka_hand")
    posture = choice.posture("elbow_up")
    report = MaxSpeedSearch(posture, DEFAULT_WALL, setting=QpSetting("crb"), tolerance=0.05, jobs=2, choice=choice).run()
    data = report.to_json()
    robot = choice.model()
    terms = robot.terms(np.array(data["q_impact"]))
    assert np.linalg.norm(terms.contact_point - robot.contact_point(posture.q)) < 0.01
    expected = closed_form_max_speed(robot, terms, DEFAULT_WALL.normal, Setting("crb"))
    assert data["predicted_max_speed"]["crb"] == pytest.approx(expected.speed)
    assert data["qp_limited_speed"] == pytest.approx(expected.speed, rel=0.05)
    assert data["qp_max_velocity_ratio"] < 1.0
    below = [e for e in report.evaluations if e.reference_speed <= report.simulated_max_speed]
    assert below and not any(e.violated for e in below)


def test_unknown_stance_is_bad_input():
    with pytest.raises(BadInputError):
        search_stance(RobotModel("g1"), "kneeling")


class ThresholdPlant:
    """A stance plant whose trial fails above ``threshold`` (m/s commanded) and records every
    commanded speed; the trial's record is no QP's."""

    def __init__(self, threshold: float):
        self.threshold, self.asked = threshold, []

    def trial(self, robot, stance, q, speed, source):
        self.asked.append(speed)
        failed = "foot_lift" if speed > self.threshold else ""
        held = SimpleNamespace(foot_slip=0.0, foot_lift=float(bool(failed)))
        return SimpleNamespace(normal_speed=speed, contact_speed=0.9 * speed, max_velocity_ratio=0.5, held=held, fell=False,
                               first_failure=failed, failure_times={failed: 0.001} if failed else {}, record=None)


@pytest.mark.parametrize("reference", [None, 0.4])
def test_a_stance_search_asks_its_checks_at_factors_of_the_reference_it_is_given(reference):
    """``SpeedChecks(factors, reference)``: after the bisection, one trial asked at each factor times
    the reference given (a closed form the caller took, as the frictional one), or times the
    stance's frictionless crb closed form when none is given; the bisection does not depend on it."""
    robot = g1_model()
    plant = ThresholdPlant(0.6)
    result = search_stance(robot, "parallel", plant=plant, tolerance=0.1, checks=SpeedChecks((0.9, 1.3), reference))
    expected = result.predicted["crb"].speed if reference is None else reference
    assert plant.asked[-2:] == [0.9 * expected, 1.3 * expected]
    assert {f: e.reference_speed for f, e in result.checks.items()} == {0.9: 0.9 * expected, 1.3: 1.3 * expected}
    assert result.simulated_reference <= 0.6 < result.simulated_reference + 0.1
    assert all(e.violated == (e.reference_speed > 0.6) for e in result.checks.values())


def test_the_qp_driven_step_stance_asked_for_nine_tenths_of_its_closed_form_reaches_it_and_stands():
    """The step stance (the left sole on a 10 cm step), its trial driven by the whole-body QP
    asked for 0.9 of the crb closed form: the contact speed within 10 % of the asked speed's share
    (0.81 to 0.99 of the closed form), no measured failure (joint velocity, slip, lift, capture,
    fall) and every QP cycle OK."""
    robot = g1_model()
    q = stance_posture(robot, robot.description.stances["step"])
    limit = closed_form_max_speed(robot, robot.terms(q), NORMAL, Setting("crb")).speed
    trial = StancePlant().trial(robot, "step", q, 0.9 * limit, source=QpCommand())
    assert 0.81 * limit <= trial.contact_speed <= 0.99 * limit
    assert trial.failures == () and trial.record.not_ok == 0


def test_an_approach_that_reaches_a_velocity_limit_below_the_lowest_speed_is_one_line_of_bad_input(tmp_path, capsys):
    """An arm whose joint velocity limits (0.01 rad/s, the least a description takes) stop the
    approach below the search's lowest speed: nothing to bisect, one line of bad input (the
    bracket's width once gave a NaN number of rounds)."""
    path = _user_arm(tmp_path, limits={"ddq_max": 15.0, "dddq_max": 7500.0, "dq_max": 0.01})
    code, out, err = run(capsys, "max-speed", "--robot", str(path), "--posture", "elbow_up")
    one_line_bad_input(code, out, err, "below the search's lowest speed 0.02 m/s")
