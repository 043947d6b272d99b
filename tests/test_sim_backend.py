"""The sim backend (``sim.sim_backend``) steps the plant as ``sim.runner.run_trial`` does, so a
run's log keeps the dataset's torque timing."""

import numpy as np

from conftest import JOINTS
from impactqp.controller.model.robot_description import PANDA
from impactqp.sim.runner import run_trial
from impactqp.sim.trial_sources import CommandReplay
from impactqp.sim.scene import build_scene

DT = 1e-3


def test_the_run_log_keeps_the_dataset_torque_timing(retract_run):
    """Row k's tau is the torque applied over period k (docs/dataset.md), as in the logs of
    sim.runner.run_trial: the run's commands replayed by run_trial from the run's start give
    the run's states and torques (the last row keeps the torque read with its own state)."""
    _, result, _ = retract_run
    log = result.log
    surface = PANDA.postures["elbow_up"].surface
    again = run_trial(build_scene(surface), CommandReplay(log.dq_cmd, JOINTS), log.q[0], log.dq[0], len(log) * DT)
    np.testing.assert_allclose(again.dq, log.dq, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(again.tau[:-1], log.tau[:-1], rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(log.tau[-1], log.tau[-2])
