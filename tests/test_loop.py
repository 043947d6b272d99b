"""The loop runner (``controller.runtime.loop``) on the simulated Panda: the watchdog trips on
every fault and brakes with continuous commands, any failure of a read, the filter or the log
ends in the braking sequence and ``robot.stop()``, a paced run reports its cycle statistics and
what a real robot would have stopped on."""

import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS, ForwardingRobot, assert_continuous_within_limits
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.runtime.command_filter import CommandFilter
from impactqp.controller.runtime.loop import BRAKING, ControlLoop, missed_in_a_row
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
                state = replace(state, q=np.full(JOINTS, np.nan))
            elif self.fault == "nan_tau_ext":
                state = replace(state, tau_ext=np.full(JOINTS, np.nan))
            elif self.fault == "stale":
                state = replace(state, t=state.t - self.period)
        return state


class Clock:
    """A clock that only moves when told: the cycle times of a test do not depend on the machine."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class FaultySession(ImpactSession):
    """The impact session, raising or running late (2.5 periods on ``clock``) from cycle ``at`` on."""

    def __init__(self, config, model, fault: str, at: int, clock: Clock):
        super().__init__(config, model)
        self.fault, self.at, self.steps, self.clock = fault, at, 0, clock

    def step(self, state):
        self.steps += 1
        if self.steps > self.at:
            if self.fault == "exception":
                raise RuntimeError("injected")
            if self.fault == "overrun":
                self.clock.now += 2.5 * DT
        return super().step(state)


@pytest.mark.parametrize("fault", ["nan", "nan_tau_ext", "stale", "exception", "overrun"])
def test_each_fault_trips_the_watchdog_and_the_commands_stay_continuous(fault, model):
    request = RunRequest(speed=0.15, duration=0.3, unpaced=True)
    backend = build_backend(request)
    sim, config = backend.robot, backend.config
    at = 200  # mid-approach, moving at speed
    robot = FaultySim(sim, fault, at) if fault in ("nan", "nan_tau_ext", "stale") else sim
    clock = Clock()  # every cycle takes no time, but the late ones
    session = (
        FaultySession(config, model, fault, at, clock) if fault in ("exception", "overrun")
        else ImpactSession(config, model)
    )
    loop = ControlLoop(robot, session, CommandFilter.for_robot(model, DT), deadline=DT, max_overruns=3, clock=clock)
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


class BrokenSim(ForwardingRobot):
    """The simulated Panda whose read returns a malformed state, NaN or raises at read ``at``
    (a backend bug), or whose write raises from cycle ``at`` on (a robot that stopped on its own
    reflex); it counts the calls of ``stop``."""

    def __init__(self, robot, fault: str, at: int):
        super().__init__(robot)
        self.fault, self.at, self.reads, self.writes, self.stops = fault, at, 0, 0, 0

    def read(self):
        state = self.robot.read()
        self.reads += 1
        if self.reads - 1 != self.at:
            return state
        return {
            "short_q": lambda: replace(state, q=state.q[:-1]),
            "long_dq": lambda: replace(state, dq=np.zeros(JOINTS + 1)),
            "tau_missing": lambda: replace(state, tau=None),
            "matrix_tau_ext": lambda: replace(state, tau_ext=np.zeros((JOINTS, 1))),
            "text_time": lambda: replace(state, t="soon"),
            "no_state": lambda: None,
            "nan_dq": lambda: replace(state, dq=np.full(JOINTS, np.nan)),
            "raise": lambda: (_ for _ in ()).throw(ConnectionError("injected: no state")),
        }[self.fault]()

    def write(self, dq_cmd):
        self.writes += 1
        if self.fault == "write" and self.writes > self.at:
            raise ConnectionError("injected: the robot stopped")
        self.robot.write(dq_cmd)

    def stop(self):
        self.stops += 1
        self.robot.stop()


READ_FAULTS = ["short_q", "long_dq", "tau_missing", "matrix_tau_ext", "text_time", "no_state", "nan_dq", "raise"]


@pytest.mark.parametrize("at", [1, 2, 150])
@pytest.mark.parametrize("fault", READ_FAULTS)
def test_any_read_failure_brakes_to_a_stop_and_calls_stop(fault, at, model):
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    sim, config = backend.robot, backend.config
    robot = BrokenSim(sim, fault, at)
    loop = ControlLoop(robot, ImpactSession(config, model), CommandFilter.for_robot(model, DT), deadline=float("inf"))
    result = loop.run(0.3)
    assert robot.stops == 1
    assert result.watchdog_trips == 1
    reason = {"nan_dq": "non-finite", "raise": "cannot be read"}.get(fault, "malformed state")
    assert reason in result.watchdog_reason, result.watchdog_reason
    phases = np.array(result.phases)
    assert np.all(phases[:at] != BRAKING) and np.all(phases[at:] == BRAKING)
    assert_continuous_within_limits(result.log.dq_cmd)
    assert np.all(result.log.dq_cmd[-1] == 0.0) and result.cycles == robot.writes < 300
    # one row per cycle, time increasing; the bad cycle logs no measurement (NaN), the others theirs
    assert len(result.log) == result.cycles and np.all(np.diff(result.log.t) > 0.0)
    assert np.all(np.isnan(result.log.dq[at])) and np.all(np.isfinite(np.delete(result.log.dq, at, axis=0)))


@pytest.mark.parametrize("fault", ["short_q", "no_state", "nan_dq"])
def test_a_bad_first_state_starts_nothing_but_stops(fault, model):
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    sim, config = backend.robot, backend.config
    robot = BrokenSim(sim, fault, 0)
    result = ControlLoop(robot, ImpactSession(config, model), CommandFilter.for_robot(model, DT)).run(0.3)
    assert robot.stops == 1 and result.watchdog_trips == 1
    assert np.all(result.log.dq_cmd == 0.0) and set(result.phases) == {BRAKING}


def test_a_robot_that_stops_taking_commands_ends_the_run_keeps_the_log_and_is_stopped(model):
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    sim, config = backend.robot, backend.config
    robot = BrokenSim(sim, "write", 100)
    loop = ControlLoop(robot, ImpactSession(config, model), CommandFilter.for_robot(model, DT), deadline=float("inf"))
    result = loop.run(0.3)
    assert result.watchdog_trips == 1 and "robot error" in result.watchdog_reason
    assert result.cycles == 101 and len(result.log) == 101 and robot.stops == 1


class BrokenFilter(CommandFilter):
    """The command filter, raising from call ``at`` on in every command but the braking ones
    (``part="command"``) or in every command (``part="brake"``)."""

    def __init__(self, base: CommandFilter, part: str, at: int):
        self.__dict__.update(base.__dict__)
        self.part, self.at, self.calls = part, at, 0

    def __call__(self, dq_desired):
        self.calls += 1
        braking = np.all(np.asarray(dq_desired) == 0.0)
        if self.calls > self.at and (self.part == "brake" or not braking):
            raise FloatingPointError("injected")
        return super().__call__(dq_desired)


@pytest.mark.parametrize("part", ["command", "brake"])
def test_a_filter_failure_brakes_when_it_can_and_always_stops(part, model):
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    sim, config = backend.robot, backend.config
    robot = BrokenSim(sim, "none", -1)
    command_filter = BrokenFilter(CommandFilter.for_robot(model, DT), part, 150)
    result = ControlLoop(robot, ImpactSession(config, model), command_filter, deadline=float("inf")).run(0.3)
    assert robot.stops == 1 and result.watchdog_trips == 1 and "controller exception" in result.watchdog_reason
    if part == "command":  # the braking command still comes: the ramp to zero
        assert np.all(result.log.dq_cmd[-1] == 0.0) and result.phase == BRAKING
        assert_continuous_within_limits(result.log.dq_cmd)
    else:  # no braking command can be computed: the robot is stopped at once
        assert result.cycles == 150


def test_a_log_failure_brakes_to_a_stop(model, monkeypatch):
    from impactqp.controller.runtime import loop as loop_module

    record = loop_module.LoopLog.record
    failures = []

    def failing(self, state, *args):
        if self.size == 150 and not failures:
            failures.append(1)
            raise MemoryError("injected")
        record(self, state, *args)

    monkeypatch.setattr(loop_module.LoopLog, "record", failing)
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True))
    sim, config = backend.robot, backend.config
    robot = BrokenSim(sim, "none", -1)
    loop = ControlLoop(robot, ImpactSession(config, model), CommandFilter.for_robot(model, DT), deadline=float("inf"))
    result = loop.run(0.3)
    assert robot.stops == 1 and result.watchdog_trips == 1 and "log error" in result.watchdog_reason
    assert result.phase == BRAKING and np.all(result.log.dq_cmd[-1] == 0.0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 0.05), max_size=60))
def test_missed_commands_count_every_period_an_overrun_ran_through(cycle_time):
    """Each overrun cycle misses at least one command (the watchdog's count) and one per full
    period beyond the first it lasted; a cycle on time ends the streak."""
    deadline = period = DT
    over = [c > deadline for c in cycle_time]
    longest_run = max((len(run) for run in "".join("x" if o else " " for o in over).split()), default=0)
    missed = missed_in_a_row(np.array(cycle_time), deadline, period)
    assert longest_run <= missed <= sum(int(np.ceil(c / period)) for c in cycle_time if c > deadline)
    assert missed_in_a_row(np.array([2.5e-3, 2.5e-3, 0.5e-3, 3.5e-3]), deadline, period) == 4
    assert missed_in_a_row(np.array([0.9e-3] * 5), deadline, period) == 0


def test_a_long_cycle_is_what_a_real_robot_would_stop_on(model):
    """A paced run whose one cycle takes 7 periods: the watchdog (it counts overrun cycles) lets
    the simulation go on, the result says a real robot would have stopped."""
    backend = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=False))
    sim, config = backend.robot, backend.config

    class OneLongCycle(ForwardingRobot):
        writes = 0

        def write(self, dq_cmd):
            self.writes += 1
            if self.writes == 100:
                time.sleep(7 * DT)
            self.robot.write(dq_cmd)

    loop = ControlLoop(OneLongCycle(sim), ImpactSession(config, model), CommandFilter.for_robot(model, DT))
    result = loop.run(0.3)
    assert result.missed_in_a_row >= 6 and result.robot_stop_reason


def test_a_state_is_well_formed_only_with_the_sizes_of_its_robot():
    """The watchdog's shape check: the joints' vectors, and a floating base's 13 base values
    (the dataset's base columns) when the state carries them."""
    from impactqp.controller.runtime.interface import RobotState
    from impactqp.controller.runtime.loop import BASE_VALUES, malformed, placeholder

    joints = np.zeros(JOINTS)
    assert malformed(RobotState(0.0, joints, joints, joints), JOINTS) == ""
    assert malformed(RobotState(0.0, joints, joints, joints, base=np.zeros(BASE_VALUES)), JOINTS) == ""
    assert "base is of shape (12,)" in malformed(RobotState(0.0, joints, joints, joints, base=np.zeros(12)), JOINTS)
    assert "q is of shape" in malformed(RobotState(0.0, np.zeros(JOINTS + 1), joints, joints), JOINTS)
    standing = placeholder(1.0, 0.001, JOINTS, floating=True)
    assert malformed(standing, JOINTS) == "" and np.all(np.isnan(standing.base)) and standing.t == 1.001
