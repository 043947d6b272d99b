"""Candidate causes of a sim-to-real gap: each one a small class that maps a few fitted numbers
theta onto plant overrides (``sim.plant.PlantParameters``).

Every cause is fitted in a transformed space u where the least-squares problem is well scaled:
u = log(theta) for positive quantities that span decades (inertia, damping, gains, time
constants), u = theta otherwise. A new cause (a user's own) is one more subclass of
:class:`Cause` passed to ``sim.diagnosis.diagnose(causes=...)``; it must only touch plant keys
that no other selected cause touches. Method and rules: ``docs/diagnosis.md``.

=============  ==============================================  ================================
cause          fitted parameters                               plant override keys
=============  ==============================================  ================================
armature       reflected rotor inertia per joint group:        ``armature`` (one per joint)
               a_1 (joints 1-4, large motors),
               a_2 (joints 5-7, small motors)
payload        payload mass m and its centre of mass c in the  ``payload_mass``, ``payload_com``
               tool's contact frame ``impact_tip``
friction       tool/wall Coulomb coefficient mu                ``friction``
contact        solref time constant and damping ratio          ``contact_solref``
joint_damping  viscous damping per joint group (1-4, 5-7)      ``joint_damping`` (one per joint)
servo_gain     joint-servo bandwidth omega                     ``servo_gain``
delay          measured dq and tau late by d control periods   ``sensor_delay``
velocity_scale logged dq / true dq (global; then per joint     ``sensor_velocity_scale``
               when the data support it: ``refined``)          (``sensor_joint_velocity_scale``)
torque_offset  bias of the logged torque per joint (N m)       ``sensor_torque_offset`` (per joint)
velocity_filt. time constant of a low-pass on the logged dq    ``sensor_velocity_filter``
=============  ==============================================  ================================

The last four are sensor causes (``sim.sensor``): they act on the replay's logged signals, not
on the physics, and compete with the plant causes in the same selection.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.tool_description import TOOLS, ToolDescription

from .plant import PlantParameters
from impactqp.controller.model.validation import name_in



def payload_com(tool: ToolDescription) -> tuple[float, float, float]:
    """The default payload centre of mass: the centre of the tool's contact geometry, relative to
    the contact point (the payload body's origin, ``sim.scene``)."""
    return tuple(float(x) for x in tool.geometry.centre - tool.contact_point)


# Joint groups of the Panda's drives: large motors on joints 1-4, small ones on joints 5-7.
JOINT_GROUPS = ((0, 1, 2, 3), (4, 5, 6))
GROUPED_JOINTS = sum(len(group) for group in JOINT_GROUPS)
"""The joints the groups cover: every joint of the arm."""
GRID_POINTS = {1: 7, 2: 5}


def per_group(values: tuple[float, ...]) -> list[float]:
    """The joint values (one per joint of ``JOINT_GROUPS``) of one value per joint group."""
    out = [0.0] * GROUPED_JOINTS
    for group, value in zip(JOINT_GROUPS, values):
        for j in group:
            out[j] = float(value)
    return out


def group_means(values) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return np.array([values[list(group)].mean() for group in JOINT_GROUPS])


class Cause:
    """A candidate cause: ``plant(nominal, u)`` builds the plant for the fitted vector u."""

    name: str = ""
    labels: tuple[str, ...] = ()
    log_scale: tuple[bool, ...] = ()
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()

    # A realistic range of theta and the tangential speeds (m/s; ``dataset generate`` runs them
    # at its tangential series' normal speed) a dataset needs for the cause to show, for tests
    # and benchmarks that hide it in simulated data.
    realistic: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())
    tangential_speeds_needed: tuple[float, ...] = ()

    def nominal_theta(self, nominal: PlantParameters) -> np.ndarray:
        raise NotImplementedError

    def grid(self, nominal: PlantParameters) -> list[np.ndarray]:
        """Start points of the fit (in u): the nominal value and a regular grid over the bounds
        (``GRID_POINTS`` per axis); a cause with more parameters gives its own."""
        lo, hi = self.u_bounds()
        axes = [np.linspace(a, b, GRID_POINTS[len(lo)]) for a, b in zip(lo, hi)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lo))
        return [self.to_u(self.nominal_theta(nominal))] + [np.array(p) for p in grid]

    def refined(self) -> "Cause | None":
        """The same effect with more parameters (per joint), which the search tries in place of
        this cause once it is chosen, and keeps when the data support it; None: no refinement."""
        return None

    def settling_trials(self, index: int, side: str, known: float, normal_speeds: np.ndarray) -> str:
        """Plain words for the trials that would bound parameter ``index`` on ``side`` ("below"
        or "above") when the data leave it open there; ``known`` is the closed end of its
        interval (the fitted value when both ends are open), ``normal_speeds`` the reference
        normal speeds (m/s) of the dataset's trials."""
        return "more trials: other postures and a wider range of normal speeds"

    def overrides(self, theta: np.ndarray) -> dict:
        raise NotImplementedError

    def theta_of(self, overrides: dict) -> np.ndarray:
        """The fitted numbers theta read back from plant overrides (inverse of ``overrides``)."""
        raise NotImplementedError

    # transformed space -------------------------------------------------------------
    def to_u(self, theta: np.ndarray) -> np.ndarray:
        theta = np.clip(np.asarray(theta, float), self.lower, self.upper)
        return np.where(self.log_scale, np.log(np.maximum(theta, 1e-12)), theta)

    def to_theta(self, u: np.ndarray) -> np.ndarray:
        return np.where(self.log_scale, np.exp(u), u)

    def u_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.to_u(self.lower), self.to_u(self.upper)

    def plant(self, nominal: PlantParameters, u: np.ndarray) -> PlantParameters:
        return replace(nominal, **self.overrides(self.to_theta(u)))


class ArmatureCause(Cause):
    """Reflected rotor inertia, one value per joint group (the drives of joints 1-4 and 5-7)."""

    name = "armature"
    labels = ("armature joints 1-4 (kg m^2)", "armature joints 5-7 (kg m^2)")
    log_scale = (True, True)
    lower, upper = (1e-3, 1e-3), (5.0, 5.0)
    realistic = ((0.2, 0.05), (1.5, 0.4))

    def nominal_theta(self, nominal):
        return np.maximum(group_means(nominal.for_joints(GROUPED_JOINTS).armature), self.lower)

    def overrides(self, theta):
        return {"armature": per_group(theta)}

    def theta_of(self, overrides):
        return group_means(overrides["armature"])

    def settling_trials(self, index, side, known, normal_speeds):
        joints = "1-4" if index == 0 else "5-7"
        return (
            f"faster impacts (higher normal speeds) at postures whose jump loads joints {joints}, "
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


class JointDampingCause(Cause):
    """Viscous joint damping, one value per joint group (joints 1-4 and 5-7)."""

    name = "joint_damping"
    labels = ("joint damping joints 1-4 (N m s/rad)", "joint damping joints 5-7 (N m s/rad)")
    log_scale = (True, True)
    lower, upper = (1e-2, 1e-2), (200.0, 200.0)
    realistic = ((1.0, 0.3), (4.0, 1.5))

    def nominal_theta(self, nominal):
        return np.maximum(group_means(nominal.for_joints(GROUPED_JOINTS).joint_damping), self.lower)

    def overrides(self, theta):
        return {"joint_damping": per_group(theta)}

    def theta_of(self, overrides):
        return group_means(overrides["joint_damping"])

    def settling_trials(self, index, side, known, normal_speeds):
        joints = "1-4" if index == 0 else "5-7"
        return f"trials that move joints {joints} faster before the impact (higher approach speeds)"


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


def default_causes(
    joints: int, surface_friction: float = DEFAULT_WALL.friction, tool: ToolDescription = TOOLS["impact_tip"]
) -> list[Cause]:
    """Every candidate cause, for a robot of ``joints`` joints and a surface of friction
    ``surface_friction`` hit with ``tool``."""
    return [
        ArmatureCause(),
        PayloadCause(tool),
        FrictionCause(surface_friction),
        ContactCause(),
        JointDampingCause(),
        ServoGainCause(),
        DelayCause(),
        VelocityScaleCause(joints),
        TorqueOffsetCause(joints),
        VelocityFilterCause(),
    ]


CAUSE_NAMES = tuple(
    kind.name for kind in (
        ArmatureCause, PayloadCause, FrictionCause, ContactCause, JointDampingCause, ServoGainCause, DelayCause,
        VelocityScaleCause, TorqueOffsetCause, VelocityFilterCause,
    )
)
"""The names of ``default_causes``, in its order."""
SENSOR_CAUSE_NAMES = ("delay", "velocity_scale", "torque_offset", "velocity_filter")
PLANT_CAUSE_NAMES = tuple(name for name in CAUSE_NAMES if name not in SENSOR_CAUSE_NAMES)


def cause_named(name: str, joints: int) -> Cause:
    """The cause ``name`` of ``default_causes`` for a robot of ``joints`` joints."""
    name_in(name, CAUSE_NAMES, "the cause")
    return next(cause for cause in default_causes(joints) if cause.name == name)


def realistic_hidden_effect(name: str, rng: np.random.Generator, joints: int) -> tuple[dict, list[float]]:
    """A random realistic value of a cause (uniform in its ``realistic`` range) on a robot of
    ``joints`` joints: the plant overrides and the tangential speeds the dataset needs to make
    the effect observable."""
    cause = cause_named(name, joints)
    theta = rng.uniform(*cause.realistic)
    return cause.overrides(theta), list(cause.tangential_speeds_needed)
