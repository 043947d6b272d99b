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
    The offline rule of :mod:`impactqp.controller.measured.impact`, made causal: the impact is
    detected at the first sample where |r_j| > max(``torque_threshold``, ``NOISE_SIGMAS`` sigma_j)
    for some joint j, with sigma_j = 1.4826 median |r_j| (robust noise level). The two differences
    (``docs/robot-loop.md``): offline, sigma comes from the whole log and the rule is applied to
    the 10-sample trend residual of the measured torque; online, sigma comes from the first
    ``calibration_samples`` residuals (the floor alone applies before), and the rule is applied to
    the momentum residual, which needs no trend because it is zero without contact.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from impactqp.controller.model.robot import NQ, PandaModel
from impactqp.controller.model.validation import BadInputError

from .impact import DEFAULT_TORQUE_THRESHOLD, NOISE_SIGMAS

DEFAULT_OBSERVER_GAIN = 200.0
DEFAULT_CALIBRATION_SAMPLES = 100


class MomentumObserver:
    """The generalized-momentum observer of the module docstring (its own Pinocchio data)."""

    def __init__(self, robot: PandaModel, dt: float, gain: float = DEFAULT_OBSERVER_GAIN):
        if not (np.isfinite(gain) and gain > 0.0 and gain * dt < 1.0):
            raise BadInputError(f"observer gain {gain} 1/s must be > 0 and below 1/dt")
        self.model = robot.model
        self.data = robot.model.createData()
        self.dt = float(dt)
        self.gain = float(gain)
        self.residual = np.zeros(NQ)
        self._p0 = np.zeros(NQ)
        self._integral = np.zeros(NQ)
        self._drift = np.zeros(NQ)  # C^T dq - g of the previous sample
        self._started = False

    def _momentum_and_drift(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        model, data = self.model, self.data
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        C = pin.computeCoriolisMatrix(model, data, q, dq)
        g = pin.computeGeneralizedGravity(model, data, q)
        np.subtract(C.T @ dq, g, out=self._drift)
        return M @ dq

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
    """Latching online detector (module docstring): ``update(t, residual)`` once per sample."""

    def __init__(
        self,
        torque_threshold: float = DEFAULT_TORQUE_THRESHOLD,
        noise_sigmas: float = NOISE_SIGMAS,
        calibration_samples: int = DEFAULT_CALIBRATION_SAMPLES,
    ):
        if not (np.isfinite(torque_threshold) and torque_threshold > 0.0):
            raise BadInputError(f"torque_threshold = {torque_threshold} N m must be > 0")
        self.torque_threshold = float(torque_threshold)
        self.noise_sigmas = float(noise_sigmas)
        self.calibration = np.zeros((int(calibration_samples), NQ))
        self.samples = 0
        self.threshold = np.full(NQ, self.torque_threshold)
        self.detected = False
        self.t_detect: float | None = None
        self.joint: int | None = None

    def update(self, t: float, residual: np.ndarray) -> bool:
        """True at the sample where the impact is detected (and only there)."""
        if self.detected:
            return False
        magnitude = np.abs(residual)
        if not np.all(np.isfinite(magnitude)):
            return False
        if np.any(magnitude > self.threshold):
            self.detected = True
            self.t_detect = float(t)
            self.joint = int(np.argmax(magnitude / self.threshold))
            return True
        if self.samples < len(self.calibration):
            self.calibration[self.samples] = magnitude
            self.samples += 1
            if self.samples == len(self.calibration):
                sigma = 1.4826 * np.median(self.calibration, axis=0)
                self.threshold = np.maximum(self.torque_threshold, self.noise_sigmas * sigma)
        return False
