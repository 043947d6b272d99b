"""The check of the G1's closed form against simulation and the report of its stance search
(scenarios/stance_check.py)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.max_speed import HELD_CONTACT_CRITERIA, Bound, MaxSpeed, Setting, closed_form_max_speed
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.scenarios.max_speed_search import StancePlant
from impactqp.scenarios.stance_evaluation import StanceMaxSpeed
from impactqp.scenarios.stance_check import (
    CRITERION_OF,
    CheckRow,
    check_summary,
    speed_figure,
    trial_at_contact_speed,
)
from impactqp.sim.observed_criteria import WITH_HELD_CONTACTS
from impactqp.sim.runner import NORMAL

FAILURES = tuple(c.name for c in WITH_HELD_CONTACTS)


class FakeTrial:
    def __init__(self, failures, slipped=False, times=None):
        self.failures = tuple(failures)
        self.failure_times = times or {f: 1e-3 * k for k, f in enumerate(failures)}
        self.first_failure = failures[0] if failures else ""
        self.failure_time = self.failure_times.get(self.first_failure, float("nan"))
        self.fell = "fell" in failures
        self.held = SimpleNamespace(slipped=slipped)  # the foot frame's displacement beyond 5 mm
        self.feasible = not failures


def test_check_summary_counts_below_and_above():
    """A fall measures no closed-form criterion; below, a slip onset or a 5 mm displacement counts."""
    rows = [
        CheckRow("a", 0.5, "capture", FakeTrial([])),
        CheckRow("a", 0.8, "capture", FakeTrial([], slipped=True)),
        CheckRow("a", 0.9, "capture", FakeTrial(["joint_velocity"])),
        CheckRow("a", 0.95, "capture", FakeTrial(["foot_slip"])),
        CheckRow("a", 1.2, "capture", FakeTrial(["capture", "fell"])),
        CheckRow("a", 1.3, "capture", FakeTrial(["foot_lift", "capture"])),
        CheckRow("a", 1.32, "capture", FakeTrial(["foot_slip", "capture"], times={"foot_slip": 0.0, "capture": 0.0})),
        CheckRow("a", 1.35, "capture", FakeTrial(["fell"])),
        CheckRow("a", 1.4, "capture", FakeTrial([])),
    ]
    assert check_summary(rows) == {
        "below": 4, "below_fell_or_slipped": 2, "below_infeasible": 2, "above": 5,
        "above_binding_first": 1, "above_binding_tied": 1, "above_binding_failed": 3, "above_feasible": 1,
    }


def test_each_measured_failure_is_the_closed_form_criterion_of_its_name():
    assert CRITERION_OF == {c: c for c in HELD_CONTACT_CRITERIA}
    assert "fell" in FAILURES and "fell" not in CRITERION_OF
    assert set(CRITERION_OF) <= set(FAILURES)


def test_figure_is_a_png(tmp_path):
    predicted = {
        "crb": MaxSpeed(1.0, "capture", "edge 0", 0, {"capture": Bound(1.0, "edge 0")}),
        "gm": MaxSpeed(math.inf, "", "", 0, {}),
    }
    q = np.zeros(RobotModel("g1").model.nq)
    results = [StanceMaxSpeed(name, q, predicted, 1.2, 0.9, "foot_slip") for name in ("a", "b")]
    path = speed_figure(results, tmp_path / "f.png", "test")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_trial_reaches_the_asked_contact_speed():
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["close"])
    trial = trial_at_contact_speed(robot, "close", q, 0.3, StancePlant())
    assert trial.contact_speed == pytest.approx(0.3, rel=0.02)


def test_on_the_step_the_scripted_hand_stands_below_the_closed_form_and_lifts_a_foot_above_it():
    """The step stance (the left sole on a 10 cm step): at 0.9x the crb closed form the trial has
    no onset and no fall; at 1.1x the binding criterion (foot lift) fails."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["step"])
    best = closed_form_max_speed(robot, robot.terms(q), NORMAL, Setting("crb"))
    assert best.criterion == "foot_lift"
    below = trial_at_contact_speed(robot, "step", q, 0.9 * best.speed, StancePlant())
    assert below.contact_speed == pytest.approx(0.9 * best.speed, rel=0.02)
    assert below.feasible and not below.fell
    above = trial_at_contact_speed(robot, "step", q, 1.1 * best.speed, StancePlant())
    assert above.contact_speed == pytest.approx(1.1 * best.speed, rel=0.02)
    assert "foot_lift" in above.failures
