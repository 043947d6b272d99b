"""The impact session (``controller.runtime.session``) in runs on the simulated Panda: the impact is
detected within 5 ms of the contact start (also with an unmodelled payload), and each post-impact
mode does what it says (retract leaves the wall, hold presses, continue re-contacts); the detector's
residual is the robot's external-torque estimate only when it is one (not the measured joint
torque itself), else the momentum observer."""

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from conftest import JOINTS, assert_continuous_within_limits
from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.runtime.interface import RobotState
from impactqp.controller.runtime.session import ESTIMATE, OBSERVER, ImpactSession, residual_source
from impactqp.scenarios.run import RunRequest, contact_start, run

RETRACT_WINDOW = 0.05
DETECTION_WINDOW = 5e-3

torques = arrays(float, JOINTS, elements=st.floats(-80.0, 80.0))


@pytest.fixture(scope="module")
def model():
    return PandaModel()


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
    surface = PANDA.postures["elbow_up"].surface
    distance = surface.signed_distance(model.contact_point(log.q[-1]))
    assert distance > 0.01
    phases = np.array(result.phases)
    detect = int(np.searchsorted(log.t, report["impact"]["time"]))
    assert set(phases[:detect]) == {"approach"} and phases[detect] == "retract"
    assert_continuous_within_limits(log.dq_cmd)
    assert report["watchdog_trips"] == 0 and report["phase"] == "stop"
    assert np.all(log.dq_cmd[-1] == 0.0)


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


@given(torques, torques)
def test_an_estimate_is_used_only_when_it_differs_from_the_measured_torque(tau, tau_ext):
    q, dq = np.zeros(JOINTS), np.zeros(JOINTS)
    assert residual_source(RobotState(0.0, q, dq, tau)) == OBSERVER
    assert residual_source(RobotState(0.0, q, dq, tau, tau.copy())) == OBSERVER
    expected = OBSERVER if np.array_equal(tau, tau_ext) else ESTIMATE
    assert residual_source(RobotState(0.0, q, dq, tau, tau_ext)) == expected


def test_a_session_fed_the_measured_torque_as_estimate_runs_the_observer():
    model = PandaModel()
    posture = PANDA.postures["elbow_up"]
    session = ImpactSession(ControllerConfig.approach(posture.surface, 0.15), model)
    q, dq = posture.q, np.zeros(JOINTS)
    tau = model.terms(q, dq).h
    session.start(RobotState(0.0, q, dq, tau, tau))
    assert session.residual_source == OBSERVER
    extra = np.linspace(1.0, 2.0, JOINTS)  # a joint torque that did not move the arm: held by an external one
    pushed = tau + extra
    residual = session.residual(RobotState(1e-3, q, dq, pushed, pushed))
    observer = session.observer
    assert np.array_equal(residual, observer.residual)
    assert np.allclose(residual, -observer.gain * observer.dt * extra, atol=1e-9)
