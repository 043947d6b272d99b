"""One stance trial read for the search (scenarios/stance_evaluation.py)."""

import dataclasses
from functools import partial

import numpy as np

from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.scenarios.max_speed_search import STANCE_HIGHEST_SPEED, StancePlant
from impactqp.scenarios.stance_evaluation import WALL_NOT_REACHED, StanceEvaluation
from impactqp.sim.trial_sources import SCRIPTED


def test_a_stance_trial_whose_hand_never_reaches_the_wall_is_a_failed_evaluation():
    """The G1 with every torque limit at 0.1 N m (the least a description takes) cannot bring its
    hand to the wall at the search's highest speed: the trial is a failed evaluation named
    ``WALL_NOT_REACHED`` (no contact), which the bisection counts as any failure; it was an
    internal error."""
    g1 = ROBOTS["g1"]
    weak = RobotModel(dataclasses.replace(g1, tau_max=np.full(len(g1.joints), 0.1)))
    q = stance_posture(weak, g1.stances["parallel"])
    run = partial(StancePlant().trial, weak, "parallel", q, source=SCRIPTED)
    evaluation = StanceEvaluation.of_speed(run, STANCE_HIGHEST_SPEED)
    assert evaluation.violated and evaluation.first_failure == WALL_NOT_REACHED
    assert evaluation.contact_speed == 0.0 and evaluation.reference_speed == STANCE_HIGHEST_SPEED
