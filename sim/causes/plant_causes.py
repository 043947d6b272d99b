"""The causes that change the simulated physics: the drives' armature, joint damping and joint
friction, a
payload, the tool/wall friction and contact, and the joint servo (``sim.causes`` lists them)."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.tool_description import TOOLS, ToolDescription

from .cause import Cause, JointGroupCause, group_name, payload_com


class ArmatureCause(JointGroupCause):
    """Reflected rotor inertia, one value per joint group (the drives of the shoulder and elbow,
    and of the wrist)."""

    name = "armature"
    key, quantity, unit = "armature", "armature", "kg m^2"
    log_scale = (True, True)
    lower, upper = (1e-3, 1e-3), (5.0, 5.0)
    realistic = ((0.2, 0.05), (1.5, 0.4))

    def settling_trials(self, index, side, known, normal_speeds):
        return (
            f"faster impacts (higher normal speeds) at postures whose jump loads {group_name(self.groups[index])}, "
            "e.g. the contact normal across those joints' axes"
        )


class PayloadCause(Cause):
    """A point mass m on the hand at c, in the tool's contact frame ``impact_tip`` (the hand's
    axes, origin at the tool tip; the tool points along +z, so the hand side is z < 0)."""

    name = "payload"
    labels = ("payload mass (kg)", "payload CoM x (m)", "payload CoM y (m)", "payload CoM z (m)")
    log_scale = (False, False, False, False)
    lower, upper = (0.0, -0.1, -0.1, -0.3), (5.0, 0.1, 0.1, 0.05)
    realistic = ((0.3, -0.02, -0.02, -0.10), (2.0, 0.02, 0.02, -0.02))
    MASS_GRID = 7

    def __init__(self, tool: ToolDescription = TOOLS["impact_tip"]):
        self.com = payload_com(tool)

    def nominal_theta(self, nominal):
        com = nominal.payload_com if nominal.payload_mass > 0.0 else self.com
        return np.array([nominal.payload_mass, *com])

    def grid(self, nominal):
        """The nominal value, then masses over the bounds with the CoM at the tool's centre."""
        masses = np.linspace(self.lower[0], self.upper[0], self.MASS_GRID)
        return [self.to_u(self.nominal_theta(nominal))] + [np.array([m, *self.com]) for m in masses]

    def overrides(self, theta):
        return {"payload_mass": float(theta[0]), "payload_com": [float(x) for x in theta[1:4]]}

    def theta_of(self, overrides):
        return np.array([float(overrides["payload_mass"]), *map(float, overrides["payload_com"])])

    def settling_trials(self, index, side, known, normal_speeds):
        if index == 0:
            return "trials at more postures, with the hand in other orientations against gravity"
        return "trials at postures that turn the hand about each axis, so gravity acts on the payload's lever arm"


class FrictionCause(Cause):
    name = "friction"
    labels = ("friction coefficient",)
    log_scale = (False,)
    lower, upper = (0.0,), (1.5,)
    realistic = ((0.3,), (0.8,))
    # friction only shows in impacts that keep sliding: tangential speeds of several mu v_n
    tangential_speeds_needed = (0.3, 0.6)
    SLIDING_FACTORS = (3.0, 6.0)
    MIN_MU_FOR_ADVICE = 0.1

    def __init__(self, surface_friction: float = DEFAULT_WALL.friction):
        self.surface_friction = surface_friction

    def nominal_theta(self, nominal):
        return np.array([self.surface_friction if nominal.friction is None else nominal.friction])

    def settling_trials(self, index, side, known, normal_speeds):
        """Open above: the impacts stick, so mu >= ``known`` only. The tool slides through an
        impact when its tangential speed exceeds about mu times the normal speed (the tangential
        impulse is capped at mu times the normal one), so trials at SLIDING_FACTORS times
        ``known`` times the dataset's normal speeds make it slide."""
        mu = max(known, self.MIN_MU_FOR_ADVICE)
        low, high = (float(np.min(normal_speeds)), float(np.max(normal_speeds))) if len(normal_speeds) else (0.1, 0.1)
        speeds = f"{self.SLIDING_FACTORS[0] * mu * low:.2f} to {self.SLIDING_FACTORS[1] * mu * high:.2f} m/s"
        normal = f"{low:.2f} m/s" if high - low < 5e-3 else f"{low:.2f} to {high:.2f} m/s"
        if side == "above":
            return (
                f"every impact sticks, so mu is only known to be at least {known:.2f}: trials with tangential "
                f"speeds of several mu times the normal speed ({speeds} at this dataset's normal speeds of "
                f"{normal}) would make the tool slide and bound it"
            )
        return "trials with a small tangential speed, whose impacts stick for a moderate mu"

    def overrides(self, theta):
        return {"friction": float(theta[0])}

    def theta_of(self, overrides):
        return np.array([float(overrides["friction"])])


class ContactCause(Cause):
    name = "contact"
    labels = ("solref time constant (s)", "solref damping ratio")
    log_scale = (True, True)
    lower, upper = (1e-3, 0.05), (0.05, 5.0)
    realistic = ((0.004, 0.3), (0.012, 0.8))

    def nominal_theta(self, nominal):
        return np.array(nominal.contact_solref, dtype=float)

    def overrides(self, theta):
        return {"contact_solref": [float(theta[0]), float(theta[1])]}

    def theta_of(self, overrides):
        return np.array(overrides["contact_solref"], dtype=float)


class JointDampingCause(JointGroupCause):
    """Viscous joint damping, one value per joint group."""

    name = "joint_damping"
    key, quantity, unit = "joint_damping", "joint damping", "N m s/rad"
    log_scale = (True, True)
    lower, upper = (1e-2, 1e-2), (200.0, 200.0)
    realistic = ((1.0, 0.3), (4.0, 1.5))

    def settling_trials(self, index, side, known, normal_speeds):
        return f"trials that move {group_name(self.groups[index])} faster before the impact (higher approach speeds)"


class JointFrictionCause(JointGroupCause):
    """Dry (Coulomb) joint friction, one torque per joint group: MuJoCo's friction loss, which
    opposes a joint's motion with up to that torque. Beside the viscous ``joint_damping``
    (torque c dq), it is the torque f sign(dq) that every identified model of a geared arm has;
    the servo's torque before contact shows it, the same at every approach speed."""

    name = "joint_friction"
    key, quantity, unit = "joint_friction", "joint friction", "N m"
    log_scale = (True, True)
    lower, upper = (1e-2, 1e-2), (10.0, 10.0)
    realistic = ((0.3, 0.15), (1.3, 0.6))

    def settling_trials(self, index, side, known, normal_speeds):
        return (f"trials that move {group_name(self.groups[index])} in both directions before the impact "
                "(other postures and normals)")


class ServoGainCause(Cause):
    name = "servo_gain"
    labels = ("servo bandwidth (rad/s)",)
    log_scale = (True,)
    # Above about 300 rad/s the 1 kHz zero-order-hold servo loses its stability margin.
    lower, upper = (1.0,), (300.0,)
    realistic = ((60.0,), (150.0,))

    def nominal_theta(self, nominal):
        return np.array([nominal.servo_gain])

    def overrides(self, theta):
        return {"servo_gain": float(theta[0])}

    def theta_of(self, overrides):
        return np.array([float(overrides["servo_gain"])])
