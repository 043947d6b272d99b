"""The impact session's choice of the detector's residual: the robot's external-torque estimate
only when it is one (not the measured joint torque itself), else the momentum observer."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.config import ControllerConfig
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.robot import NQ, PandaModel
from impactqp.scenarios.robot.interface import RobotState
from impactqp.scenarios.robot.session import ESTIMATE, OBSERVER, ImpactSession, residual_source

torques = arrays(float, NQ, elements=st.floats(-80.0, 80.0))


@given(torques, torques)
def test_an_estimate_is_used_only_when_it_differs_from_the_measured_torque(tau, tau_ext):
    q, dq = np.zeros(NQ), np.zeros(NQ)
    assert residual_source(RobotState(0.0, q, dq, tau)) == OBSERVER
    assert residual_source(RobotState(0.0, q, dq, tau, tau.copy())) == OBSERVER
    expected = OBSERVER if np.array_equal(tau, tau_ext) else ESTIMATE
    assert residual_source(RobotState(0.0, q, dq, tau, tau_ext)) == expected


def test_a_session_fed_the_measured_torque_as_estimate_runs_the_observer():
    model = PandaModel()
    posture = POSTURES["elbow_up"]
    session = ImpactSession(ControllerConfig.approach(posture.surface, 0.15), model)
    q, dq = posture.q, np.zeros(NQ)
    tau = model.terms(q, dq).h
    session.start(RobotState(0.0, q, dq, tau, tau))
    assert session.residual_source == OBSERVER
    extra = np.linspace(1.0, 2.0, NQ)  # a joint torque that did not move the arm: held by an external one
    pushed = tau + extra
    residual = session.residual(RobotState(1e-3, q, dq, pushed, pushed))
    observer = session.observer
    assert np.array_equal(residual, observer.residual)
    assert np.allclose(residual, -observer.gain * observer.dt * extra, atol=1e-9)
