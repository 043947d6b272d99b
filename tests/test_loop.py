"""The loop runner (``controller.runtime.loop``) on the simulated Panda: the watchdog trips on
every fault and brakes with continuous commands, a backend failure ends the run, and a paced run
reports its cycle statistics."""

import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from conftest import ForwardingRobot, assert_continuous_within_limits
from impactqp.controller.model.robot import NQ, PandaModel
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.runtime.loop import BRAKING, ControlLoop
from impactqp.controller.runtime.session import ImpactSession
from impactqp.scenarios.run import RunRequest, build_backend, run

DT = 1e-3


@pytest.fixture(scope="module")
def model():
    return PandaModel()


class FaultySim(ForwardingRobot):
    """The simulated Panda with one fault injected in the state read at cycle ``at``."""

    def __init__(self, robot, fault: str, at: int):
        super().__init__(robot)
        self.fault, self.at, self.reads = fault, at, 0

    def read(self):
        state = self.robot.read()
        self.reads += 1
        if self.reads - 1 == self.at:
            if self.fault == "robot_error":
                raise ConnectionError("injected: the robot stopped")
            if self.fault == "nan":
                state = replace(state, q=np.full(NQ, np.nan))
            elif self.fault == "nan_tau_ext":
                state = replace(state, tau_ext=np.full(NQ, np.nan))
            elif self.fault == "stale":
                state = replace(state, t=state.t - self.period)
        return state


class FaultySession(ImpactSession):
    """The impact session, raising or running late from cycle ``at`` on."""

    def __init__(self, config, model, fault: str, at: int):
        super().__init__(config, model)
        self.fault, self.at, self.steps = fault, at, 0

    def step(self, state):
        self.steps += 1
        if self.steps > self.at:
            if self.fault == "exception":
                raise RuntimeError("injected")
            if self.fault == "overrun":
                time.sleep(2.5 * DT)
        return super().step(state)


@pytest.mark.parametrize("fault", ["nan", "nan_tau_ext", "stale", "exception", "overrun"])
def test_each_fault_trips_the_watchdog_and_the_commands_stay_continuous(fault, model):
    request = RunRequest(speed=0.15, duration=0.3, unpaced=True)
    sim, config, _ = build_backend(request)
    at = 200  # mid-approach, moving at speed
    robot = FaultySim(sim, fault, at) if fault in ("nan", "nan_tau_ext", "stale") else sim
    session = (
        FaultySession(config, model, fault, at) if fault in ("exception", "overrun") else ImpactSession(config, model)
    )
    deadline = DT if fault == "overrun" else float("inf")
    loop = ControlLoop(robot, session, CommandFilter.for_robot(model, DT), deadline=deadline, max_overruns=3)
    result = loop.run(0.3)
    assert result.watchdog_trips == 1
    expected = {
        "nan": "non-finite", "nan_tau_ext": "non-finite", "stale": "stale", "exception": "exception",
        "overrun": "overruns",
    }[fault]
    assert expected in result.watchdog_reason
    phases = np.array(result.phases)
    tripped = np.flatnonzero(phases == BRAKING)
    assert tripped.size > 0 and np.all(np.isin(phases[tripped[0] :], [BRAKING, "stop"]))
    assert tripped[0] <= at + 3
    assert_continuous_within_limits(result.log.dq_cmd)
    assert np.max(np.abs(result.log.dq_cmd[tripped[0] - 1])) > 0.01  # it was moving at the trip
    # the run ends once the braking command is zero, long before the 0.3 s it was asked for
    assert np.all(result.log.dq_cmd[-1] == 0.0) and np.any(result.log.dq_cmd[-2] != 0.0)
    assert result.phase == BRAKING


def test_a_backend_failure_ends_the_run_and_keeps_the_log(model):
    sim, config, _ = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    loop = ControlLoop(
        FaultySim(sim, "robot_error", 100), ImpactSession(config, model), CommandFilter.for_robot(model, DT),
        deadline=float("inf"),
    )
    result = loop.run(0.3)
    assert result.watchdog_trips == 1 and "robot error" in result.watchdog_reason
    assert result.cycles == 100 and len(result.log) == 100


def test_two_seconds_of_paced_control_report_cycle_statistics(model, capsys):
    # the overrun trip is off: the run measures 2 s of control (the watchdog tests trip it)
    report, result = run(RunRequest(speed=0.15, duration=2.0, unpaced=False, log=None, max_overruns=10**9))
    print(f"paced sim: {report['cycles']} cycles, {report['overruns']} overruns, cycle_us {report['cycle_us']}, "
          f"period error p99 {np.percentile(result.period_error_us, 99):.0f} us, trips {report['watchdog_trips']}")
    assert report["cycles"] >= 2000
    stats = report["cycle_us"]
    assert 0.0 < stats["p50"] <= stats["p99"] <= stats["max"]
    assert 0 <= report["overruns"] <= report["cycles"]
    assert_continuous_within_limits(result.log.dq_cmd)
    assert Counter(result.phases)["stop"] >= 1
