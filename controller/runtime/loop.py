"""The loop runner: one fixed-period cycle, a deadline check, the command filter and a watchdog.

Start: the first state is read, the session prepares its controllers from it (their solvers'
set-up), and only then ``robot.start()`` begins real time (a robot expects a command every
period from there on; a backend whose state moved on meanwhile returns its newest state).

One cycle (``command`` then ``record``; a robot that calls us every period, such as libfranka's
callback API, runs the same two in ``callback_cycle``, the robot doing the read and the write)::

    state = robot.read()                       (a paced backend blocks until the period starts)
    watchdog: read failed? malformed, NaN or stale state?      -> trip
    command = session.step(state)              (an exception    -> trip)
    dq_cmd = filter(command.dq_cmd)            (or filter.brake() once tripped or stopping)
    robot.write(dq_cmd)
    cycle time = write done - read returned;  > deadline: overrun;  N overruns in a row -> trip

The watchdog latches: after a trip every command is the filter's braking command, which ramps the
commanded velocity to zero within the velocity, acceleration and jerk limits
(``controller.runtime.command_filter``), so the commands stay continuous; the run ends when the command
is zero. At the end of the run (the duration, a stop request such as Ctrl-C, or a replay's last
state) the loop brakes the same way until the command is zero, then calls ``robot.stop()``.

Failures: a read that raises or returns a malformed state (wrong type or shape: a backend bug)
trips the watchdog like a NaN state, and the cycle logs NaN values; an exception of the
controller, the filter or the log trips it too, and braking goes on. Only two failures end the
run at once: a write that raises (a robot that stopped on its own reflex: no command reaches it
any more) and a braking command that cannot be computed. ``robot.stop()`` is called on every way
out, the watchdog reason says why and the log is kept.

Every cycle is logged (t, q, dq, tau and the command actually sent) in the dataset format: row
k's tau is the torque applied over period k, which the state of cycle k + 1 reports
(``LoopLog.record``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from impactqp.controller.measured.dataset_robot import BASE_COLUMNS
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.validation import BadInputError, all_finite

from .command_filter import CommandFilter
from .interface import RobotInterface, RobotState
from .session import ImpactSession

DEFAULT_MAX_OVERRUNS = 5
BASE_VALUES = len(BASE_COLUMNS)  # a floating base's state in a RobotState and a log row
BRAKING = "brake"
STOPPING = "stop"
STOPPED_SPEED = 1e-9
MAX_STOP_CYCLES = 2000


class Watchdog:
    """Trips on a non-finite state (t, q, dq, tau or tau_ext), a stale state, a controller exception or ``max_overruns``
    consecutive overruns; latched until the end of the run. ``reason`` says why. ``joints`` is the
    number of values of a well-formed state's vectors."""

    def __init__(self, joints: int, max_overruns: int = DEFAULT_MAX_OVERRUNS):
        if max_overruns < 1:
            raise BadInputError(f"max_overruns = {max_overruns} must be >= 1")
        self.joints = int(joints)
        self.max_overruns = int(max_overruns)
        self.consecutive_overruns = 0
        self.tripped = False
        self.reason = ""
        self.trips = 0
        self._last_t = -math.inf

    def trip(self, reason: str) -> None:
        if not self.tripped:
            self.tripped = True
            self.reason = reason
            self.trips += 1

    def check_state(self, state: RobotState) -> bool:
        """Trip on a malformed (wrong type or shape), non-finite or stale state; whether the
        state is well-formed, i.e. safe to log."""
        problem = malformed(state, self.joints)
        if problem:
            self.trip(f"malformed state: {problem}")
            return False
        parts = [state.q, state.dq, state.tau] + [x for x in (state.tau_ext, state.base) if x is not None]
        finite = all_finite(*parts) and math.isfinite(state.t)
        if not finite:
            self.trip(f"non-finite state at t = {state.t}")
        elif state.t <= self._last_t:
            self.trip(f"stale state: time {state.t} s does not increase")
        if math.isfinite(state.t):
            self._last_t = max(self._last_t, state.t)
        return True

    def record_cycle(self, overrun: bool) -> None:
        self.consecutive_overruns = self.consecutive_overruns + 1 if overrun else 0
        if self.consecutive_overruns >= self.max_overruns:
            self.trip(f"{self.consecutive_overruns} overruns in a row")


def malformed(state, joints: int) -> str:
    """What makes ``state`` unusable as a :class:`RobotState` of ``joints`` joints ("" when
    nothing): a backend bug, never a value the watchdog can judge."""
    if not isinstance(state, RobotState):
        return f"a {type(state).__name__}, not a RobotState"
    if isinstance(state.t, bool) or not isinstance(state.t, (int, float, np.integer, np.floating)):
        return f"t is a {type(state.t).__name__}"
    named = [("q", state.q, joints), ("dq", state.dq, joints), ("tau", state.tau, joints)]
    named += [] if state.tau_ext is None else [("tau_ext", state.tau_ext, joints)]
    named += [] if state.base is None else [("base", state.base, BASE_VALUES)]
    for name, value, size in named:
        if not isinstance(value, np.ndarray) or value.shape != (size,) or value.dtype.kind not in "fiu":
            shape = getattr(value, "shape", None)
            return f"{name} is {'a ' + type(value).__name__ if shape is None else f'of shape {shape}'}, not {size} numbers"
    return ""


def placeholder(t: float, period: float, joints: int, floating: bool = False) -> RobotState:
    """The state logged for a cycle whose read failed or was malformed: the next period's time
    and NaN values for the ``joints`` joints (and a floating base's state: ``floating``) (no
    measurement), so the log stays one row per cycle with increasing time."""
    nan = np.full(joints, np.nan)
    return RobotState(t + period, nan, nan, nan, base=np.full(BASE_VALUES, np.nan) if floating else None)


class LoopLog:
    """Per-cycle records of ``joints`` joints in arrays preallocated for ``capacity`` cycles (no
    allocation per cycle)."""

    def __init__(self, capacity: int, joints: int, floating: bool = False):
        self.size = 0
        self.base = np.zeros((capacity, BASE_VALUES)) if floating else None
        self.t = np.zeros(capacity)
        self.q = np.zeros((capacity, joints))
        self.dq = np.zeros((capacity, joints))
        self.tau = np.zeros((capacity, joints))
        self.dq_cmd = np.zeros((capacity, joints))
        self.cycle_time = np.zeros(capacity)
        self.start_time = np.zeros(capacity)
        self.phase: list[str] = []

    def record(self, state: RobotState, dq_cmd: np.ndarray, phase: str, cycle_time: float, start_time: float) -> None:
        k = self.size
        self.t[k] = state.t
        self.q[k] = state.q
        self.dq[k] = state.dq
        if self.base is not None:
            self.base[k] = state.base
        # A state's tau is the torque of the period before it (``RobotState``), while the
        # dataset's tau[k] is the torque applied over period k (docs/dataset.md): the read of
        # cycle k fills row k - 1. The last row keeps the torque read with its own state (no
        # later read reports its period).
        if k > 0:
            self.tau[k - 1] = state.tau
        self.tau[k] = state.tau
        self.dq_cmd[k] = dq_cmd
        self.cycle_time[k] = cycle_time
        self.start_time[k] = start_time
        self.phase.append(phase)
        self.size = k + 1

    def trial_log(self, force: tuple[np.ndarray, np.ndarray] | None) -> TrialLog:
        n = self.size
        log = TrialLog(self.t[:n], self.q[:n], self.dq[:n], self.tau[:n], self.dq_cmd[:n])
        if self.base is not None:
            log.base = self.base[:n]
        if force is not None:
            log.force_t, log.force = force
        return log


@dataclass(frozen=True)
class LoopResult:
    """What one run did: cycle statistics, watchdog, impact and the log."""

    cycles: int
    overruns: int
    cycle_us: dict
    period_error_us: np.ndarray
    watchdog_trips: int
    watchdog_reason: str
    phases: list[str]
    log: TrialLog
    session: ImpactSession
    interrupted: bool = False  # a stop request (Ctrl-C, SIGTERM) ended the run
    missed_in_a_row: int = 0  # the longest streak of periods without a command on time
    max_overruns: int = DEFAULT_MAX_OVERRUNS  # the watchdog's budget of overruns in a row

    @property
    def phase(self) -> str:
        return self.phases[-1] if self.phases else ""

    @property
    def robot_stop_reason(self) -> str:
        """Why a real robot would have stopped on this run ("" when it would not): a watchdog
        trip, or ``max_overruns`` commands in a row that missed their period. The watchdog counts
        overrun cycles, so a paced simulation goes on after one long cycle, while a robot would
        have gone without a command for every period of it (libfranka:
        ``communication_constraints_violation``)."""
        if self.watchdog_trips:
            return f"the watchdog tripped ({self.watchdog_reason})"
        if self.missed_in_a_row >= self.max_overruns:
            return (
                f"{self.missed_in_a_row} periods in a row without a command on time "
                f"(the budget is {self.max_overruns - 1})"
            )
        return ""


def missed_in_a_row(cycle_time: np.ndarray, deadline: float, period: float) -> int:
    """The longest streak of periods without a command on time: a cycle longer than the
    deadline misses max(1, ceil(cycle time / period) - 1) commands (the robot's periods it ran
    through), and a cycle within the deadline ends the streak."""
    streak = longest = 0
    for c in np.asarray(cycle_time, dtype=float).tolist():
        streak = streak + max(1, math.ceil(c / period) - 1) if c > deadline else 0
        longest = max(longest, streak)
    return longest


def cycle_statistics(cycle_time_s: np.ndarray) -> dict:
    us = np.asarray(cycle_time_s) * 1e6
    if us.size == 0:
        return {"p50": 0.0, "p99": 0.0, "max": 0.0}
    return {"p50": float(np.median(us)), "p99": float(np.percentile(us, 99)), "max": float(us.max())}


class ControlLoop:
    """Runs an :class:`ImpactSession` on a :class:`RobotInterface` (module docstring).

    ``deadline``: the longest cycle time (s) that is not an overrun (default: the period);
    ``clock``: the clock (s) that measures the cycle times.
    """

    def __init__(
        self,
        robot: RobotInterface,
        session: ImpactSession,
        command_filter: CommandFilter,
        *,
        deadline: float | None = None,
        max_overruns: int = DEFAULT_MAX_OVERRUNS,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.clock = clock
        self.robot = robot
        self.session = session
        self.filter = command_filter
        self.joints = len(command_filter.dq_max)  # the filter limits every actuated joint of the robot
        self.floating = False  # whether the robot's states carry a floating base's (the first state says)
        self.deadline = robot.period if deadline is None else float(deadline)
        self.watchdog = Watchdog(self.joints, max_overruns)
        self.stop_requested = False
        self.robot_failed = False
        self.overruns = 0
        self.log: LoopLog | None = None
        self.cycles = self.k = self.stop_cycles = 0
        self.stopping = False

    def request_stop(self) -> None:
        """Brake to a stop at the next cycle (a signal handler may call it)."""
        self.stop_requested = True

    def run(self, duration: float) -> LoopResult:
        """Run for ``duration`` s, then brake to a stop. Whatever fails after the first read (a
        read, a malformed state, the controller, the filter, the log) trips the watchdog and
        ends in the braking sequence; ``robot.stop()`` is called on every way out."""
        robot, watchdog = self.robot, self.watchdog
        self.cycles = int(round(duration / robot.period))
        state = robot.read()  # before real time: nothing moves yet, a failure is reported as it is
        self.floating = isinstance(state, RobotState) and state.base is not None
        self.log = LoopLog(self.cycles + MAX_STOP_CYCLES + 1, self.joints, self.floating)
        if not watchdog.check_state(state):
            state = placeholder(0.0, robot.period, self.joints, self.floating)
        elif not watchdog.tripped:
            self.session.start(state)
            self.filter.reset(state.dq)
        if robot.drives_cycles:  # the robot calls ``callback_cycle`` once per period
            try:
                robot.drive(self.callback_cycle)
            except Exception as error:  # the robot stopped by itself (e.g. its own reflex)
                self._robot_error(error)
            finally:
                self._stop()
            return self._result()
        try:
            newest = robot.start()
            if newest is not None and watchdog.check_state(newest):
                state = newest
            elif newest is not None:
                state = placeholder(state.t, robot.period, self.joints, self.floating)
        except BaseException:
            self._stop()
            raise
        try:
            self._cycle(state)
        except Exception as error:  # e.g. no braking command can be computed: stop() is all that is left
            watchdog.trip(f"loop failure: {type(error).__name__}: {error}")
        finally:
            self._stop()
        return self._result()

    def _cycle(self, state: RobotState) -> None:
        """The cycles of the run (module docstring), from the first state to the end of braking."""
        while True:
            started = self.clock()
            dq_cmd, phase = self.command(state)
            try:
                self.robot.write(dq_cmd)
            except Exception as error:  # the robot stopped by itself (e.g. its own reflex)
                self._robot_error(error)
                self._record(state, dq_cmd, phase, self.clock() - started, started)
                return
            if self.record(state, dq_cmd, phase, started):
                return
            state = self._read(state, check=not self.stopping)

    def command(self, state: RobotState) -> tuple[np.ndarray, str]:
        """The command of the cycle of ``state`` and its phase: the session's, filtered; the
        filter's braking command once tripped or stopping."""
        self.stopping = self.stop_requested or self.k >= self.cycles
        if self.stopping:
            self.stop_cycles += 1
            return self.brake(), STOPPING
        if self.watchdog.tripped:
            return self.brake(), BRAKING
        try:
            command = self.session.step(state)
            return self.filter(command.dq_cmd[-self.joints:]), command.phase  # the actuated joints' part
        except Exception as error:  # the robot must keep getting commands
            self.watchdog.trip(f"controller exception: {type(error).__name__}: {error}")
            return self.brake(), BRAKING

    def record(self, state: RobotState, dq_cmd: np.ndarray, phase: str, started: float) -> bool:
        """Account and log the cycle that began at ``started`` once its command is out; True when
        the run is over (stopped, braked to zero, or the backend has no more states)."""
        elapsed = self.clock() - started
        overrun = elapsed > self.deadline
        self.overruns += overrun
        if not self.stopping:
            self.watchdog.record_cycle(overrun)
        self._record(state, dq_cmd, phase, elapsed, started)
        self.k += 1
        if self.stopping and self.stop_cycles >= MAX_STOP_CYCLES:
            return True
        if (self.stopping or self.watchdog.tripped) and np.max(np.abs(dq_cmd)) <= STOPPED_SPEED:
            return True
        return self.robot.finished

    def callback_cycle(self, state: RobotState) -> tuple[np.ndarray, bool]:
        """One cycle for a robot that calls us every period (``RobotInterface.drive``): the
        watchdog's state check, the command, its accounting; (command, run over)."""
        started = self.clock()
        if not self.stopping and not self.watchdog.check_state(state):
            last_t = self.log.t[self.log.size - 1] if self.log.size else 0.0
            state = placeholder(last_t, self.robot.period, self.joints, self.floating)
        dq_cmd, phase = self.command(state)
        return dq_cmd, self.record(state, dq_cmd, phase, started)

    def _read(self, previous: RobotState, check: bool) -> RobotState:
        """The next state; a read that raises or returns a malformed state trips the watchdog
        (braking goes on, and a placeholder of NaN values is logged for the cycle)."""
        try:
            state = self.robot.read()
        except Exception as error:
            message = " ".join(str(error).split())  # one line, whatever the bindings' message holds
            self.watchdog.trip(f"robot error: the state cannot be read: {type(error).__name__}: {message}")
            return placeholder(previous.t, self.robot.period, self.joints, self.floating)
        usable = self.watchdog.check_state(state) if check else not malformed(state, self.joints)
        return state if usable else placeholder(previous.t, self.robot.period, self.joints, self.floating)

    def _record(self, state: RobotState, dq_cmd: np.ndarray, phase: str, elapsed: float, started: float) -> None:
        """Log the cycle; a failure of the log trips the watchdog (the commands matter more)."""
        try:
            self.log.record(state, dq_cmd, phase, elapsed, started)
        except Exception as error:
            self.watchdog.trip(f"log error: {type(error).__name__}: {error}")

    def _stop(self) -> None:
        """``robot.stop()``, its failure recorded as a robot error (unless the robot already failed)."""
        try:
            self.robot.stop()
        except Exception as error:
            if not self.robot_failed:
                self._robot_error(error)

    def brake(self) -> np.ndarray:
        """The filter's next braking command; a residue below ``STOPPED_SPEED`` (rounding of the
        jerk-limited ramp) is sent as exactly zero, a step far inside every limit."""
        dq_cmd = self.filter.brake()
        if np.max(np.abs(dq_cmd)) <= STOPPED_SPEED:
            dq_cmd[:] = 0.0
        return dq_cmd

    def _robot_error(self, error: Exception) -> None:
        """The backend failed: no command can reach the robot any more; the run ends, its log
        is kept and the watchdog says why."""
        self.robot_failed = True
        message = " ".join(str(error).split())  # one line, whatever the bindings' message holds
        self.watchdog.trip(f"robot error: {type(error).__name__}: {message}")
        self.robot.failed(error)

    def _result(self) -> LoopResult:
        log = self.log
        intervals = np.diff(log.start_time[: log.size])
        return LoopResult(
            cycles=log.size,
            overruns=int(self.overruns),
            cycle_us=cycle_statistics(log.cycle_time[: log.size]),
            period_error_us=np.abs(intervals - self.robot.period) * 1e6,
            watchdog_trips=self.watchdog.trips,
            watchdog_reason=self.watchdog.reason,
            phases=list(log.phase),
            log=log.trial_log(self.robot.force_log()),
            session=self.session,
            interrupted=self.stop_requested,
            missed_in_a_row=missed_in_a_row(log.cycle_time[: log.size], self.deadline, self.robot.period),
            max_overruns=self.watchdog.max_overruns,
        )
