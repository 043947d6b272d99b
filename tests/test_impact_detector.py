"""The momentum observer estimates the external joint torque; the online rule latches once."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.measured.impact import DEFAULT_TORQUE_THRESHOLD, NOISE_SIGMAS
from impactqp.controller.measured.impact_detector import ImpactDetector, MomentumObserver
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.robot import NQ, PandaModel

DT = 1e-3


@pytest.fixture(scope="module")
def robot():
    return PandaModel()


def simulate(robot, tau, tau_ext, steps, substeps=20):
    """Forward dynamics (Pinocchio ABA, fine semi-implicit Euler) under the joint torque
    tau(q, dq) held over each control period and the external joint torque tau_ext(k); yields
    (q, dq, held torque) at every control sample."""
    model, data = robot.model, robot.model.createData()
    q, dq = POSTURES["elbow_up"].q.copy(), np.zeros(NQ)
    h = DT / substeps
    for k in range(steps):
        held = tau(q, dq)
        yield q.copy(), dq.copy(), held
        for _ in range(substeps):
            dq = dq + h * pin.aba(model, data, q, dq, held + tau_ext(k))
            q = q + h * dq


def gravity_hold(robot):
    data = robot.model.createData()
    return lambda q, dq: pin.computeGeneralizedGravity(robot.model, data, q) + np.array([3, -2, 1, 2, 0.5, 0.3, 0.2])


def run_observer(robot, tau_ext, steps):
    observer = MomentumObserver(robot, DT)
    tau = gravity_hold(robot)
    residuals, tau_previous = [], None
    for q, dq, held in simulate(robot, tau, tau_ext, steps):
        if tau_previous is None:
            observer.reset(q, dq)
            residuals.append(np.zeros(NQ))
        else:
            residuals.append(observer.update(q, dq, tau_previous).copy())
        tau_previous = held
    return np.array(residuals)


def test_observer_residual_stays_near_zero_without_external_torque(robot):
    residual = run_observer(robot, lambda k: np.zeros(NQ), 200)
    # far below the detection floor: the residual is the integration error only
    assert np.abs(residual).max() < 0.05 * DEFAULT_TORQUE_THRESHOLD


def test_observer_residual_follows_an_external_torque_step_as_a_first_order_filter(robot):
    step = np.array([2.0, -1.0, 1.5, 1.0, 0.5, -0.5, 0.3])
    residual = run_observer(robot, lambda k: step if k >= 50 else np.zeros(NQ), 120)
    gain = 200.0
    expected = step * (1.0 - (1.0 - gain * DT) ** 20)
    assert np.allclose(residual[70], expected, atol=0.1 * np.abs(step).max())
    assert np.allclose(residual[-1], step, atol=0.05)


@settings(max_examples=60, deadline=None)
@given(st.floats(0.001, 0.04), st.integers(0, 299), st.floats(2.0, 20.0))
def test_detector_fires_once_at_the_first_sample_above_the_threshold(noise, onset, jump):
    rng = np.random.default_rng(0)
    detector = ImpactDetector(calibration_samples=100)
    residual = rng.normal(0.0, noise, size=(400, NQ))
    residual[100 + onset :, 2] += jump * max(DEFAULT_TORQUE_THRESHOLD, NOISE_SIGMAS * noise * 1.5)
    fired = [detector.update(0.001 * k, r) for k, r in enumerate(residual)]
    assert sum(fired) == 1
    first = fired.index(True)
    assert first <= 100 + onset
    # the threshold after calibration is the offline rule's: max(floor, 6 sigma)
    assert np.all(detector.threshold >= DEFAULT_TORQUE_THRESHOLD)
    if first >= 100:
        assert np.all(np.abs(residual[100:first]) <= detector.threshold)
        assert np.any(np.abs(residual[first]) > detector.threshold)


def test_detector_ignores_a_non_finite_residual():
    detector = ImpactDetector()
    assert not detector.update(0.0, np.full(NQ, np.nan))
    assert not detector.detected
