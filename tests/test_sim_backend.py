"""The sim backend (``sim.sim_backend``) steps the plant as ``sim.runner.run_trial`` does, so a
run's log keeps the dataset's torque timing; and once real time begins, no compiled kernel is
loaded (a kernel's first call costs milliseconds: a late command)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

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


LATE_KERNELS = textwrap.dedent(
    """
    import os, sys, tempfile
    from numba.core import dispatcher
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.scenarios.run import RunRequest, run
    from impactqp.sim.sim_backend import SimRobot

    real_time, late = [False], []
    add_overload, start = dispatcher.Dispatcher.add_overload, SimRobot.start

    def recorded(self, result):
        if real_time[0]:
            late.append(self.py_func.__qualname__)
        return add_overload(self, result)

    def started(self):
        real_time[0] = True
        return start(self)

    dispatcher.Dispatcher.add_overload, SimRobot.start = recorded, started
    os.chdir(tempfile.mkdtemp())
    report, result = run(RunRequest(duration=0.6, unpaced=True, choice=RobotChoice.of(sys.argv[1])))
    assert result.phase != "approach" and report["impact"]["detected"], report
    print(",".join(late))
    """
)


@pytest.mark.parametrize("robot", ["panda", "g1"])
def test_no_compiled_kernel_is_loaded_once_real_time_begins(robot):
    """A fresh interpreter (no kernel loaded yet) runs the sim backend through its impact: every
    kernel of the controller, the filter and the plant is loaded (from numba's cache, or
    compiled) before ``SimRobot.start``, none in the loop."""
    out = subprocess.run([sys.executable, "-c", LATE_KERNELS, robot], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"kernels first called in the real-time loop: {out.stdout.strip()}"
