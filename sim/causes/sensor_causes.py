"""The causes that change what the sensors log, not the physics (``sim.sensor``): a delay, a
velocity scale (global, then per joint), a torque offset per joint and a velocity filter."""

from __future__ import annotations

import numpy as np

from .cause import Cause


class DelayCause(Cause):
    """The measured dq and tau logged d control periods late (fractional: interpolated)."""

    name = "delay"
    labels = ("sensor delay (control periods)",)
    log_scale = (False,)
    lower, upper = (0.0,), (10.0,)
    realistic = ((1.0,), (4.0,))

    def nominal_theta(self, nominal):
        return np.array([nominal.sensor_delay])

    def overrides(self, theta):
        return {"sensor_delay": float(theta[0])}

    def theta_of(self, overrides):
        return np.array([float(overrides["sensor_delay"])])


class VelocityScaleCause(Cause):
    """The logged dq a constant factor times the true velocity (all ``joints`` joints)."""

    name = "velocity_scale"
    labels = ("velocity scale",)
    log_scale = (False,)
    lower, upper = (0.7,), (1.4,)
    realistic = ((1.04,), (1.1,))

    def __init__(self, joints: int):
        self.joints = joints

    def nominal_theta(self, nominal):
        return np.array([nominal.sensor_velocity_scale])

    def overrides(self, theta):
        return {"sensor_velocity_scale": float(theta[0])}

    def theta_of(self, overrides):
        return np.array([float(overrides["sensor_velocity_scale"])])

    def refined(self):
        return JointVelocityScaleCause(self.joints)


class JointVelocityScaleCause(Cause):
    """The logged dq of each of the ``joints`` joints its own factor times the true velocity: the
    refinement of ``VelocityScaleCause`` (same name; the global scale folded into the joints' own)."""

    name = "velocity_scale"
    separable = True

    def __init__(self, joints: int):
        self.joints = joints
        self.labels = tuple(f"velocity scale joint {j + 1}" for j in range(joints))
        self.log_scale = (False,) * joints
        self.lower, self.upper = (0.7,) * joints, (1.4,) * joints

    def nominal_theta(self, nominal):
        scales = nominal.for_joints(self.joints).sensor_joint_velocity_scale
        return nominal.sensor_velocity_scale * np.array(scales, dtype=float)

    def grid(self, nominal):
        """The nominal scales only: the search starts it from the fitted global scale."""
        return [self.to_u(self.nominal_theta(nominal))]

    def overrides(self, theta):
        return {"sensor_velocity_scale": 1.0, "sensor_joint_velocity_scale": [float(x) for x in theta]}

    def theta_of(self, overrides):
        scales = overrides.get("sensor_joint_velocity_scale", (1.0,) * self.joints)
        return float(overrides.get("sensor_velocity_scale", 1.0)) * np.array(scales, dtype=float)


class TorqueOffsetCause(Cause):
    """A constant bias of the logged torque, per joint (``joints`` of them)."""

    name = "torque_offset"
    separable = True

    def __init__(self, joints: int):
        self.joints = joints
        self.labels = tuple(f"torque offset joint {j + 1} (N m)" for j in range(joints))
        self.log_scale = (False,) * joints
        self.lower, self.upper = (-5.0,) * joints, (5.0,) * joints
        self.realistic = ((-1.5,) * joints, (1.5,) * joints)

    def nominal_theta(self, nominal):
        return np.array(nominal.for_joints(self.joints).sensor_torque_offset, dtype=float)

    def grid(self, nominal):
        """The nominal offsets only: the torque residual is linear in the offsets, so the fit
        needs no other start."""
        return [self.to_u(self.nominal_theta(nominal))]

    def overrides(self, theta):
        return {"sensor_torque_offset": [float(x) for x in theta]}

    def theta_of(self, overrides):
        return np.array(overrides["sensor_torque_offset"], dtype=float)


class VelocityFilterCause(Cause):
    """The logged dq a first-order low-pass estimate of the true velocity (time constant, s)."""

    name = "velocity_filter"
    labels = ("velocity filter time constant (s)",)
    log_scale = (True,)
    lower, upper = (1e-4,), (0.05,)
    realistic = ((0.002,), (0.008,))

    def nominal_theta(self, nominal):
        return np.array([max(nominal.sensor_velocity_filter, self.lower[0])])

    def overrides(self, theta):
        return {"sensor_velocity_filter": float(theta[0])}

    def theta_of(self, overrides):
        return np.array([float(overrides["sensor_velocity_filter"])])
