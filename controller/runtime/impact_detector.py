"""Online impact detection from a joint-torque residual, one sample per control period.

Residual
    The robot's own external-torque estimate when it gives one (Franka: ``tau_ext_hat_filtered``),
    else the generalized-momentum observer of De Luca et al. on the measured joint torque
    (:class:`MomentumObserver`). With p = M(q) dq the generalized momentum,

        r_k = K (p_k - p_0 - dt sum_{i<k} (tau_i + C(q_i, dq_i)^T dq_i - g(q_i) + r_i))

    is a first-order filter (bandwidth K) of the external joint torque tau_ext: p' = tau +
    C^T dq - g + tau_ext. tau_i is the joint torque that acted over period i (held constant);
    the drift C^T dq - g is integrated with the trapezoidal rule over each period.

Rule
    The offline rule of :mod:`impactqp.controller.measured.impact`, made causal. After
    ``settle_samples`` ignored ones, the next ``calibration_samples`` residuals are the
    contact-free reference (no detection during either):
    per joint, the bias b_j = median r_j and the robust noise level sigma_j = 1.4826
    median |r_j - b_j|. After them the impact is detected at the first sample where
    |r_j - b_j| > max(``torque_threshold``, ``NOISE_SIGMAS`` sigma_j) for some joint j.

    The bias matters on a robot: an external-torque estimate is offset by every unmodelled load
    (a tool of mass m whose centre of mass sits at lever arm l from a joint axis adds up to
    m g l, about 0.7 N m for 0.5 kg at 0.14 m, above the 0.3 N m floor), and the momentum
    observer converges to the same offset with time constant 1/K: its first samples, still
    rising, would inflate sigma, so the session lets it settle for ``OBSERVER_SETTLE`` time
    constants (residual error e^-5 of the offset) before the calibration. The differences from the
    offline rule (``docs/robot-loop.md``): offline, sigma comes from the whole log and the rule
    is applied to the 10-sample trend residual of the measured torque, which removes offsets and
    slopes; online, bias and sigma come from the calibration window, so the robot must not touch
    anything during it, and a load offset that changes after it is not removed.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError, positive

from impactqp.constraints.impact_model import DROPPED, FOLLOWING
from impactqp.controller.measured.impact import DEFAULT_TORQUE_THRESHOLD, NOISE_SIGMAS

DEFAULT_OBSERVER_GAIN = 200.0
DEFAULT_CALIBRATION_SAMPLES = 100
OBSERVER_SETTLE = 5.0  # time constants 1/K


class MomentumObserver:
    """The generalized-momentum observer of the module docstring (its own Pinocchio data)."""

    def __init__(self, robot: PandaModel, dt: float, gain: float = DEFAULT_OBSERVER_GAIN):
        if not (np.isfinite(gain) and gain > 0.0 and gain * dt < 1.0):
            raise BadInputError(f"observer gain {gain} 1/s must be > 0 and below 1/dt")
        self.model = robot.model
        self.data = robot.model.createData()
        self.dt = float(dt)
        self.gain = float(gain)
        self.residual = np.zeros(robot.nv)
        self._p0 = np.zeros(robot.nv)
        self._integral = np.zeros(robot.nv)
        self._drift = np.zeros(robot.nv)  # C^T dq - g of the previous sample
        self._gravity, self._zero = np.zeros(robot.nv), np.zeros(robot.nv)
        self._started = False

    @property
    def settle_samples(self) -> int:
        """Periods for the response to a constant external torque to come within e^-5 of it."""
        return int(np.ceil(OBSERVER_SETTLE / (self.gain * self.dt)))

    def _momentum_and_drift(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """p = M(q) dq, as RNEA's torque at zero velocity and acceleration dq less gravity
        (M dq + g - g: no mass matrix formed), and the drift C^T dq - g into ``_drift``."""
        model, data = self.model, self.data
        g = self._gravity
        g[:] = pin.computeGeneralizedGravity(model, data, q)
        C = pin.computeCoriolisMatrix(model, data, q, dq)
        np.subtract(C.T @ dq, g, out=self._drift)
        return pin.rnea(model, data, q, self._zero, dq) - g

    def reset(self, q, dq) -> None:
        self._p0 = self._momentum_and_drift(np.asarray(q, float), np.asarray(dq, float))
        self._integral[:] = 0.0
        self.residual[:] = 0.0
        self._started = True

    def update(self, q, dq, tau_previous) -> np.ndarray:
        """r_k from the state (q_k, dq_k) and the torque that acted over the previous period."""
        if not self._started:
            self.reset(q, dq)
            return self.residual
        drift_previous = self._drift.copy()
        p = self._momentum_and_drift(np.asarray(q, float), np.asarray(dq, float))
        self._integral += self.dt * (np.asarray(tau_previous, float) + 0.5 * (drift_previous + self._drift) + self.residual)
        self.residual = self.gain * (p - self._p0 - self._integral)
        return self.residual


class ImpactDetector:
    """Latching online detector (module docstring): ``update(t, residual)`` once per sample, a
    residual of one value per joint (``joints``)."""

    def __init__(
        self,
        joints: int,
        torque_threshold: float = DEFAULT_TORQUE_THRESHOLD,
        noise_sigmas: float = NOISE_SIGMAS,
        calibration_samples: int = DEFAULT_CALIBRATION_SAMPLES,
        settle_samples: int = 0,
    ):
        positive(torque_threshold, "torque_threshold", "N m")
        positive(noise_sigmas, "noise_sigmas")
        for name, value in (("calibration_samples", calibration_samples), ("settle_samples", settle_samples)):
            if int(value) != value or value < 0:
                raise BadInputError(f"{name} = {value} must be an integer >= 0")
        self.settle_samples = int(settle_samples)
        self.ignored = 0
        self.torque_threshold = float(torque_threshold)
        self.noise_sigmas = float(noise_sigmas)
        self.calibration = np.zeros((int(calibration_samples), joints))
        self.samples = 0
        self.bias = np.zeros(joints)
        self.threshold = np.full(joints, self.torque_threshold)
        self.detected = False
        self.t_detect: float | None = None
        self.t_calibrated: float | None = None  # time of the sample that completed the calibration
        self.joint: int | None = None

    @property
    def calibrated(self) -> bool:
        return self.samples >= len(self.calibration)

    def update(self, t: float, residual: np.ndarray) -> bool:
        """True at the sample where the impact is detected (and only there); a non-finite
        residual is skipped."""
        if self.detected:
            return False
        residual = np.asarray(residual, dtype=float)
        if not np.all(np.isfinite(residual)):
            return False
        if self.ignored < self.settle_samples:
            self.ignored += 1
            return False
        if not self.calibrated:
            self.calibration[self.samples] = residual
            self.samples += 1
            if self.calibrated:
                self.t_calibrated = float(t)
                self.bias = np.median(self.calibration, axis=0)
                sigma = 1.4826 * np.median(np.abs(self.calibration - self.bias), axis=0)
                self.threshold = np.maximum(self.torque_threshold, self.noise_sigmas * sigma)
            return False
        deviation = np.abs(residual - self.bias)
        if np.any(deviation > self.threshold):
            self.detected = True
            self.t_detect = float(t)
            self.joint = int(np.argmax(deviation / self.threshold))
            return True
        return False


class VelocityJumpDetector:
    """The impact of a robot whose joint torques cannot single it out (a floating base on held
    contacts: their wrenches change with every motion), detected by the jump of its measured
    velocity, the rule of the controller's impact brake (``controller.qp.controller``): at the
    first state where, the expected impact's rows active at the last command, the contact point's
    measured speed towards the surface, -n.(J dq), falls below ``IMPACT_SPEED_DROP`` times the
    speed the last command asks there, -n.(J dq_cmd), after a sample where it did not (a drop:
    while the approach starts, the command's speed runs ahead of a body that has not yet followed,
    and at 0.4 m/s asked the rule alone fired 2 ms into the run). ``update(t, q, dq, last)`` once
    per sample with the model's state and the last Command; no calibration (``t_calibrated``
    None)."""

    def __init__(self, robot: PandaModel, impact):
        self.robot, self.impact = robot, impact
        self.data = robot.model.createData()
        self.detected = False
        self.t_detect: float | None = None
        self.t_calibrated: float | None = None
        self._following = False  # the last sample's measured speed followed its command

    def update(self, t: float, q: np.ndarray, dq: np.ndarray, last) -> bool:
        """True at the sample where the impact is detected (and only there)."""
        if self.detected or last is None or self.impact is None or not last.impact_constraints_active:
            return False
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq))):
            return False
        J = pin.computeFrameJacobian(
            self.robot.model, self.data, q, self.robot.contact_frame_id, pin.LOCAL_WORLD_ALIGNED
        )[:3]
        tracking = self.impact.speed_tracking(J, dq, last.dq_cmd)
        if tracking == DROPPED and self._following:
            self.detected, self.t_detect = True, float(t)
        self._following = tracking == FOLLOWING
        return self.detected
