"""The loop runner on the simulated Panda: impact detection, retract, watchdog, replay, pacing."""

import json
import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from impactqp.controller.command_filter import CommandFilter
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.robot import ACCELERATION_LIMIT, JERK_LIMIT, NQ, VELOCITY_LIMIT, PandaModel
from conftest import ForwardingRobot
from impactqp.scenarios.robot.loop import BRAKING, ControlLoop
from impactqp.scenarios.robot.run import RunRequest, build_backend, contact_start, controller_config, run
from impactqp.scenarios.robot.session import ImpactSession
from impactqp.sim.runner import CommandReplay, run_trial
from impactqp.sim.scene import build_scene

DT = 1e-3
TOL = 1e-9
RETRACT_WINDOW = 0.05
DETECTION_WINDOW = 5e-3


@pytest.fixture(scope="module")
def model():
    return PandaModel()


@pytest.fixture(scope="module")
def retract_run(tmp_path_factory):
    log_dir = tmp_path_factory.mktemp("run")
    report, result = run(RunRequest(speed=0.15, duration=0.6, unpaced=True, log=str(log_dir)))
    return report, result, log_dir


def assert_continuous_within_limits(dq_cmd):
    dq = np.vstack([np.zeros((2, NQ)), dq_cmd])  # every run here starts at rest
    ddq = np.diff(dq, axis=0) / DT
    jerk = np.diff(ddq, axis=0) / DT
    assert np.all(np.isfinite(dq))
    assert np.all(np.abs(dq) <= VELOCITY_LIMIT * (1 + TOL))
    assert np.all(np.abs(ddq) <= ACCELERATION_LIMIT * (1 + TOL))
    assert np.all(np.abs(jerk) <= JERK_LIMIT * (1 + TOL))


def test_an_approach_at_0_15_m_s_is_detected_within_5_ms_of_the_contact_start(retract_run):
    report, result, _ = retract_run
    t_contact = contact_start(result)
    assert t_contact is not None and report["impact"]["detected"]
    assert 0.0 <= report["impact"]["time"] - t_contact <= DETECTION_WINDOW
    assert report["impact"]["contact_speed"] == pytest.approx(0.15, rel=0.05)


def test_an_unmodelled_payload_is_not_taken_for_the_impact(tmp_path):
    # the plant carries 0.5 kg that the controller's model lacks: a constant offset of the
    # observer's residual, which the detector takes as its bias
    plant = tmp_path / "payload.json"
    plant.write_text(json.dumps({"payload_mass": 0.5, "payload_com": [0.0, 0.0, 0.05]}))
    report, result = run(RunRequest(plant_file=str(plant), speed=0.15, duration=0.6, unpaced=True))
    t_contact = contact_start(result)
    assert t_contact is not None and report["impact"]["detected"]
    assert 0.0 <= report["impact"]["time"] - t_contact <= DETECTION_WINDOW


def test_retract_leaves_the_wall_within_50_ms_without_recontact(retract_run, model):
    report, result, _ = retract_run
    log = result.log
    in_contact = np.linalg.norm(log.force, axis=1) > 0.0
    t_contact = contact_start(result)
    touching = log.force_t[in_contact]
    assert touching.max() <= t_contact + RETRACT_WINDOW
    # one contact phase: no force sample is zero between the first and the last touching one
    first, last = np.flatnonzero(in_contact)[[0, -1]]
    assert np.all(in_contact[first : last + 1])
    # the tool ends away from the wall, the phase after detection is the retract
    surface = POSTURES["elbow_up"].surface
    distance = surface.signed_distance(model.contact_point(log.q[-1]))
    assert distance > 0.01
    phases = np.array(result.phases)
    detect = int(np.searchsorted(log.t, report["impact"]["time"]))
    assert set(phases[:detect]) == {"approach"} and phases[detect] == "retract"
    assert_continuous_within_limits(log.dq_cmd)
    assert report["watchdog_trips"] == 0 and report["phase"] == "stop"
    assert np.all(log.dq_cmd[-1] == 0.0)


def test_a_replayed_trial_reproduces_the_logged_commands(retract_run):
    _, original, log_dir = retract_run
    report, replayed = run(RunRequest(backend="replay", dataset=str(log_dir), log=None))
    controlled = np.array([p not in ("stop", BRAKING) for p in original.phases])
    # the CSV keeps 10 significant digits of every logged state
    assert np.allclose(replayed.log.dq_cmd[controlled], original.log.dq_cmd[controlled], rtol=0.0, atol=1e-6)
    # the replay reports each logged torque with the next state, so its own log has the same rows
    n = len(original.log) - 1
    assert np.allclose(replayed.log.tau[:n], original.log.tau[:n], rtol=1e-9, atol=1e-6)
    assert report["impact"]["time"] == pytest.approx(original.session.detector.t_detect)


def test_the_run_log_keeps_the_dataset_torque_timing(retract_run):
    """Row k's tau is the torque applied over period k (docs/dataset.md), as in the logs of
    sim.runner.run_trial: the run's commands replayed by run_trial from the run's start give
    the run's states and torques (the last row keeps the torque read with its own state)."""
    _, result, _ = retract_run
    log = result.log
    surface = POSTURES["elbow_up"].surface
    again = run_trial(build_scene(surface), CommandReplay(log.dq_cmd), log.q[0], log.dq[0], len(log) * DT)
    np.testing.assert_allclose(again.dq, log.dq, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(again.tau[:-1], log.tau[:-1], rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(log.tau[-1], log.tau[-2])


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
    sim, config, _ = build_backend(request, model)
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


def test_the_default_configuration_approaches_the_posture_wall():
    config = controller_config(RunRequest(posture="elbow_up", speed=0.1))
    assert config.post_impact.mode == "retract"
    assert config.tasks[0].params["speed"] == 0.1


def test_a_backend_failure_ends_the_run_and_keeps_the_log(model):
    sim, config, _ = build_backend(RunRequest(speed=0.15, duration=0.3, unpaced=True), model)
    loop = ControlLoop(
        FaultySim(sim, "robot_error", 100), ImpactSession(config, model), CommandFilter.for_robot(model, DT),
        deadline=float("inf"),
    )
    result = loop.run(0.3)
    assert result.watchdog_trips == 1 and "robot error" in result.watchdog_reason
    assert result.cycles == 100 and len(result.log) == 100


@pytest.mark.parametrize("mode", ["hold", "continue"])
def test_other_post_impact_modes_switch_the_impact_constraints_off(mode, model, tmp_path):
    config_file = tmp_path / "c.toml"
    config_file.write_text(
        '[[tasks]]\ntype = "contact_approach"\nspeed = 0.15\n[[tasks]]\ntype = "damping"\n'
        f'[post_impact]\nmode = "{mode}"\n'
    )
    report, result = run(RunRequest(config_file=str(config_file), duration=0.5, unpaced=True))
    session = result.session
    assert report["impact"]["detected"] and session.controller is session.post_impact
    assert mode in result.phases and report["watchdog_trips"] == 0
    impact_aware = ("post_impact_velocity", "impulsive_torque")
    assert any(c.name.startswith(impact_aware) for c in session.approach.constraints)
    assert not any(c.name.startswith(impact_aware) for c in session.post_impact.constraints)
    assert_continuous_within_limits(result.log.dq_cmd)
    in_contact = np.linalg.norm(result.log.force, axis=1) > 0.0
    phases = int(in_contact[0]) + int(np.sum(np.diff(in_contact.astype(int)) == 1))
    if mode == "continue":
        assert phases > 1  # it keeps commanding the approach: the tool re-contacts the wall


def hold_run(tmp_path, hold_speed: float):
    config_file = tmp_path / f"hold-{hold_speed}.toml"
    config_file.write_text(
        '[[tasks]]\ntype = "contact_approach"\nspeed = 0.15\n[[tasks]]\ntype = "damping"\n'
        f'[post_impact]\nmode = "hold"\nhold_speed = {hold_speed}\n'
    )
    report, result = run(RunRequest(config_file=str(config_file), duration=1.5, unpaced=True))
    assert report["impact"]["detected"] and report["watchdog_trips"] == 0
    assert_continuous_within_limits(result.log.dq_cmd)
    log = result.log
    holding = np.array(result.phases) == "hold"
    t_end = log.t[holding][-1]
    window = (log.force_t > t_end - 0.3) & (log.force_t <= t_end)
    return np.linalg.norm(log.force[window], axis=1)


def test_hold_comes_back_to_the_wall_and_presses_with_a_force_linear_in_the_hold_speed(tmp_path):
    # the servo answers a commanded normal velocity v into the wall with a force proportional
    # to v: over the last 0.3 s of the hold the tool never leaves the wall, and doubling
    # hold_speed doubles the mean force
    slow, fast = (hold_run(tmp_path, speed) for speed in (0.02, 0.04))
    assert np.all(slow > 0.0) and np.all(fast > 0.0)
    assert fast.mean() / slow.mean() == pytest.approx(2.0, rel=0.2)
