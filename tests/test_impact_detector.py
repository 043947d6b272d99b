"""The momentum observer estimates the external joint torque; the online rule latches once."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.impact import DEFAULT_TORQUE_THRESHOLD
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.runtime.impact_detector import ImpactDetector, MomentumObserver

DT = 1e-3


@pytest.fixture(scope="module")
def robot():
    return PandaModel()


def simulate(robot, tau, tau_ext, steps, substeps=20):
    """Forward dynamics (Pinocchio ABA, fine semi-implicit Euler) under the joint torque
    tau(q, dq) held over each control period and the external joint torque tau_ext(k); yields
    (q, dq, held torque) at every control sample."""
    model, data = robot.model, robot.model.createData()
    q, dq = PANDA.postures["elbow_up"].q.copy(), np.zeros(robot.nv)
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


@settings(max_examples=50)
@given(st.integers(0, 2**32 - 1))
def test_the_observers_momentum_is_m_dq_and_its_drift_c_transpose_dq_minus_g(robot, seed):
    """p = M(q) dq (the mass matrix of CRBA, both triangles) and C(q, dq)^T dq - g(q), at random
    states: the observer forms neither M nor M dq directly."""
    rng = np.random.default_rng(seed)
    model, data = robot.model, robot.model.createData()
    q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
    dq = rng.uniform(-2.0, 2.0, robot.nv)
    observer = MomentumObserver(robot, DT)
    p = observer._momentum_and_drift(q, dq)
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    C = pin.computeCoriolisMatrix(model, data, q, dq)
    np.testing.assert_allclose(p, M @ dq, rtol=0, atol=1e-12 * (1 + np.abs(M).max() * np.abs(dq).max()))
    drift = C.T @ dq - pin.computeGeneralizedGravity(model, data, q)
    np.testing.assert_allclose(observer._drift, drift, rtol=0, atol=1e-12 * (1 + np.abs(drift).max()))


def run_observer(robot, tau_ext, steps):
    observer = MomentumObserver(robot, DT)
    tau = gravity_hold(robot)
    residuals, tau_previous = [], None
    for q, dq, held in simulate(robot, tau, tau_ext, steps):
        if tau_previous is None:
            observer.reset(q, dq)
            residuals.append(np.zeros(robot.nv))
        else:
            residuals.append(observer.update(q, dq, tau_previous).copy())
        tau_previous = held
    return np.array(residuals)


def test_observer_residual_stays_near_zero_without_external_torque(robot):
    residual = run_observer(robot, lambda k: np.zeros(robot.nv), 200)
    # far below the detection floor: the residual is the integration error only
    assert np.abs(residual).max() < 0.05 * DEFAULT_TORQUE_THRESHOLD


def test_observer_residual_follows_an_external_torque_step_as_a_first_order_filter(robot):
    step = np.array([2.0, -1.0, 1.5, 1.0, 0.5, -0.5, 0.3])
    residual = run_observer(robot, lambda k: step if k >= 50 else np.zeros(robot.nv), 120)
    gain = 200.0
    expected = step * (1.0 - (1.0 - gain * DT) ** 20)
    assert np.allclose(residual[70], expected, atol=0.1 * np.abs(step).max())
    assert np.allclose(residual[-1], step, atol=0.05)


CALIBRATION = 100
SETTLE = 25


def feed(detector, residual):
    return [detector.update(DT * k, r) for k, r in enumerate(residual)]


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.001, 0.05),
    st.lists(st.floats(-20.0, 20.0), min_size=JOINTS, max_size=JOINTS),
    st.integers(0, 199),
    st.integers(0, JOINTS - 1),
    st.sampled_from([-1.0, 1.0]),
)
def test_detector_fires_once_at_a_step_whatever_the_offset(amplitude, offset, onset, joint, sign):
    # bounded noise |u| <= a: after calibration sigma ~ 1.4826 a / 2, so the threshold
    # max(floor, 6 sigma) is above every noise sample and below a step of 20 a + 2 floor
    rng = np.random.default_rng(0)
    residual = rng.uniform(-amplitude, amplitude, size=(SETTLE + CALIBRATION + 200, JOINTS)) + np.array(offset)
    start = SETTLE + CALIBRATION + onset
    residual[start:, joint] += sign * (20.0 * amplitude + 2.0 * DEFAULT_TORQUE_THRESHOLD)
    detector = ImpactDetector(JOINTS, calibration_samples=CALIBRATION, settle_samples=SETTLE)
    fired = feed(detector, residual)
    assert sum(fired) == 1 and fired.index(True) == start
    assert detector.joint == joint and detector.t_detect == pytest.approx(DT * start)
    assert np.all(detector.threshold >= DEFAULT_TORQUE_THRESHOLD)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.001, 0.2), st.lists(st.floats(-50.0, 50.0), min_size=JOINTS, max_size=JOINTS), st.integers(0, 2**32 - 1))
def test_detection_does_not_depend_on_a_constant_offset(noise, offset, seed):
    """A constant offset of the residual (an unmodelled load) changes neither the detection
    sample nor the threshold: the rule reads r - median(r) over the calibration window."""
    rng = np.random.default_rng(seed)
    residual = rng.normal(0.0, noise, size=(SETTLE + CALIBRATION + 300, JOINTS))
    residual[SETTLE + CALIBRATION + 150 :, 3] += 1.0
    plain, shifted = ImpactDetector(JOINTS, settle_samples=SETTLE), ImpactDetector(JOINTS, settle_samples=SETTLE)
    assert feed(plain, residual) == feed(shifted, residual + np.array(offset))
    assert np.allclose(plain.threshold, shifted.threshold, rtol=1e-9, atol=1e-9)


def test_nothing_is_detected_while_settling_and_calibrating():
    detector = ImpactDetector(JOINTS, calibration_samples=CALIBRATION, settle_samples=SETTLE)
    huge = np.full((SETTLE + CALIBRATION, JOINTS), 1e3)
    assert not any(feed(detector, huge)) and detector.calibrated


def test_an_unmodelled_load_is_not_an_impact_and_a_later_contact_is(robot):
    """The observer converges to a constant external torque (a load the model lacks) within
    its settle time; the detector takes it as the bias and fires at a later torque step within
    the first-order filter's rise time to the threshold."""
    load = np.array([0.0, 4.0, 0.5, -3.0, 0.8, 0.6, 0.1])
    step = np.zeros(robot.nv)
    step[5] = 3.0
    onset = 300
    residual = run_observer(robot, lambda k: load + (step if k >= onset else 0.0), onset + 60)
    observer = MomentumObserver(robot, DT)
    detector = ImpactDetector(robot.nv, settle_samples=observer.settle_samples)
    fired = feed(detector, residual)
    assert sum(fired) == 1
    detected = fired.index(True)
    # r_j - b_j after the step is |step_j| (1 - (1 - K dt)^n) (n periods of the filter)
    gain = 200.0
    threshold = detector.threshold[5]
    rise = int(np.ceil(np.log(1.0 - threshold / step[5]) / np.log(1.0 - gain * DT)))
    assert onset <= detected <= onset + rise + 1 and detector.joint == 5


def test_detector_ignores_a_non_finite_residual():
    detector = ImpactDetector(JOINTS)
    assert not detector.update(0.0, np.full(JOINTS, np.nan))
    assert not detector.detected


@pytest.fixture(scope="module")
def standing_approach():
    """The G1's approach controller at its parallel stance, the wall 5 cm ahead of the hand, 0.8
    m/s asked, and its state."""
    from impactqp.controller.config import ControllerConfig, build_controller
    from impactqp.controller.model.humanoid_stance import stance_posture
    from impactqp.controller.model.postures import Surface
    from impactqp.controller.model.robot import RobotModel

    g1 = RobotModel("g1")
    q0 = stance_posture(g1, g1.description.stances["parallel"])
    normal = np.array([-1.0, 0.0, 0.0])
    surface = Surface(g1.terms(q0).contact_point - 0.05 * normal, normal)
    controller = build_controller(ControllerConfig.approach(surface, 0.8, robot="g1"), g1, q0)
    return g1, controller, q0


def commanded_run(controller, q0, cycles):
    """The controller fed its own command from rest for ``cycles`` cycles: its Commands."""
    controller.reset(q0, np.zeros(len(q0) - 1))
    q, dq, commands = q0, np.zeros(len(q0) - 1), []
    for _ in range(cycles):
        commands.append(controller.step(q, dq))
        q, dq = commands[-1].q_cmd, commands[-1].dq_cmd
    return commands


def test_a_body_that_has_not_yet_followed_its_command_is_no_impact(standing_approach):
    """While the approach starts, the commanded hand speed runs ahead of a body still at rest:
    the velocity rule alone (the measured speed below half the commanded) holds there, but the
    measured speed never followed the command, so nothing dropped and nothing is detected."""
    from impactqp.controller.runtime.impact_detector import VelocityJumpDetector

    g1, controller, q0 = standing_approach
    detector = VelocityJumpDetector(g1, controller.impact)
    rest = np.zeros(g1.nv)
    commands = commanded_run(controller, q0, 30)
    rule = [controller.impact.shows_jump(g1.terms(q0).J, rest, c.dq_cmd) for c in commands]
    assert any(rule) and all(c.impact_constraints_active for c in commands)
    assert not any(detector.update(0.001 * k, q0, rest, c) for k, c in enumerate(commands))


@pytest.mark.parametrize("drop_at", [5, 20])
def test_a_drop_of_the_followed_speed_is_detected_once_at_its_sample(standing_approach, drop_at):
    """The measured velocity follows the command, then the contact takes the hand's speed
    towards the wall to zero (c_r = 0): detected at that sample and only there."""
    from impactqp.controller.runtime.impact_detector import VelocityJumpDetector

    g1, controller, q0 = standing_approach
    detector = VelocityJumpDetector(g1, controller.impact)
    commands = commanded_run(controller, q0, 30)
    seen = []
    for k in range(1, len(commands)):
        q, dq = commands[k - 1].q_cmd, commands[k - 1].dq_cmd
        if k >= drop_at:
            J = g1.terms(q).J
            dq = dq - np.linalg.pinv(J) @ (J @ dq)  # the contact point's velocity taken to zero
        seen.append(detector.update(0.001 * k, q, dq, commands[k - 1]))
    assert seen.index(True) == drop_at - 1 and sum(seen) == 1
    assert detector.detected and detector.t_detect == pytest.approx(0.001 * drop_at)
