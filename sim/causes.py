"""Candidate causes of a sim-to-real gap: each one a small class that maps a few fitted numbers
theta onto plant overrides (``sim.plant.PlantParameters``).

Every cause is fitted in a transformed space u where the least-squares problem is well scaled:
u = log(theta) for positive quantities that span decades (inertia, damping, gains, time
constants), u = theta otherwise. A new cause is one more subclass registered in ``CAUSES``.

============  ===========================================  =====================================
cause         fitted parameters                             plant override keys
============  ===========================================  =====================================
armature      one reflected rotor inertia a for all joints  ``armature`` = [a] * 7
payload       payload mass m at the tool centre             ``payload_mass``, ``payload_com``
friction      tool/wall Coulomb coefficient mu              ``friction``
contact       solref time constant and damping ratio        ``contact_solref``
joint_damping one viscous damping b for all joints          ``joint_damping`` = [b] * 7
servo_gain    joint-servo bandwidth omega                   ``servo_gain``
============  ===========================================  =====================================
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot import NQ, TOOL_RADIUS

from .plant import PlantParameters
from impactqp.controller.model.validation import BadInputError

# The payload sits at the tool's centre: the contact point moved back by the sphere radius.
PAYLOAD_COM = (0.0, 0.0, -TOOL_RADIUS)


class Cause:
    """A candidate cause: ``plant(nominal, u)`` builds the plant for the fitted vector u."""

    name: str = ""
    labels: tuple[str, ...] = ()
    log_scale: tuple[bool, ...] = ()
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()

    # A realistic range of theta and the tangential speeds (m/s, at v_n = 0.12) a dataset needs
    # for the cause to show, for tests and benchmarks that hide it in simulated data.
    realistic: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())
    tangential_speeds_needed: tuple[float, ...] = ()

    def nominal_theta(self, nominal: PlantParameters) -> np.ndarray:
        raise NotImplementedError

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
    name = "armature"
    labels = ("armature (kg m^2)",)
    log_scale = (True,)
    lower, upper = (1e-3,), (5.0,)
    realistic = ((0.2,), (1.5,))

    def nominal_theta(self, nominal):
        return np.array([max(float(np.mean(nominal.armature)), self.lower[0])])

    def overrides(self, theta):
        return {"armature": [float(theta[0])] * NQ}

    def theta_of(self, overrides):
        return np.array([float(np.mean(overrides["armature"]))])


class PayloadCause(Cause):
    name = "payload"
    labels = ("payload mass (kg)",)
    log_scale = (False,)
    lower, upper = (0.0,), (5.0,)
    realistic = ((0.3,), (2.0,))

    def nominal_theta(self, nominal):
        return np.array([nominal.payload_mass])

    def overrides(self, theta):
        return {"payload_mass": float(theta[0]), "payload_com": list(PAYLOAD_COM)}

    def theta_of(self, overrides):
        return np.array([float(overrides["payload_mass"])])


class FrictionCause(Cause):
    name = "friction"
    labels = ("friction coefficient",)
    log_scale = (False,)
    lower, upper = (0.0,), (1.5,)
    realistic = ((0.3,), (0.8,))
    # friction only shows in impacts that keep sliding: tangential speeds of several mu v_n
    tangential_speeds_needed = (0.3, 0.6)

    def __init__(self, surface_friction: float = DEFAULT_WALL.friction):
        self.surface_friction = surface_friction

    def nominal_theta(self, nominal):
        return np.array([self.surface_friction if nominal.friction is None else nominal.friction])

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
    name = "joint_damping"
    labels = ("joint damping (N m s/rad)",)
    log_scale = (True,)
    lower, upper = (1e-2,), (200.0,)
    realistic = ((1.0,), (4.0,))

    def nominal_theta(self, nominal):
        return np.array([max(float(np.mean(nominal.joint_damping)), self.lower[0])])

    def overrides(self, theta):
        return {"joint_damping": [float(theta[0])] * NQ}

    def theta_of(self, overrides):
        return np.array([float(np.mean(overrides["joint_damping"]))])


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


def default_causes(surface_friction: float = DEFAULT_WALL.friction) -> list[Cause]:
    return [
        ArmatureCause(),
        PayloadCause(),
        FrictionCause(surface_friction),
        ContactCause(),
        JointDampingCause(),
        ServoGainCause(),
    ]


CAUSE_NAMES = tuple(cause.name for cause in default_causes())


def cause_named(name: str) -> Cause:
    for cause in default_causes():
        if cause.name == name:
            return cause
    raise BadInputError(f"unknown cause {name!r}; known: {', '.join(CAUSE_NAMES)}")


def realistic_hidden_effect(name: str, rng: np.random.Generator) -> tuple[dict, list[float]]:
    """A random realistic value of a cause (uniform in its ``realistic`` range): the plant
    overrides and the tangential speeds the dataset needs to make the effect observable."""
    cause = cause_named(name)
    theta = rng.uniform(*cause.realistic)
    return cause.overrides(theta), list(cause.tangential_speeds_needed)
