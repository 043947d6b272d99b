"""Plant parameters: what the simulated robot is made of beyond the URDF's rigid links.

The nominal plant (all defaults) is the clean rigid-body baseline: rigid links exactly as in the
URDF, no rotor inertia, no joint damping or friction, no payload, and a joint servo whose feedback bandwidth
(5 rad/s) is far below the impact's (the contact time constant is 7 ms), so that the simulated
jumps follow the classical prediction M^-1 J^T iota (docs/simulation.md; ``sim.runner``). Each parameter moves
the plant away from that baseline in a known direction:

==================  ===========================================================================
parameter           effect on the MuJoCo model (``apply_plant``, in ``sim.scene.build_scene``)
==================  ===========================================================================
armature            reflected rotor inertia per joint (kg m^2), ``dof_armature``: M -> M + diag
joint_damping       viscous joint damping (N m s/rad), ``dof_damping``; replaces the URDF values
joint_friction      dry (Coulomb) joint friction torque (N m), ``dof_frictionloss``: MuJoCo's
                    friction loss, a soft constraint opposing the joint's motion up to that
                    torque; replaces the URDF values
payload_mass        point mass (kg) welded to the hand, a body ``payload``
payload_com         its position (m) in the contact frame ``impact_tip``
friction            Coulomb friction of the tool/wall pair; None: the surface's own coefficient
contact_solref      MuJoCo solref (time constant s, damping ratio) of the tool/wall pair
contact_solimp      MuJoCo solimp (dmin, dmax, width m, midpoint, power) of the pair
servo_gain          bandwidth omega (rad/s) of the computed-torque joint servo (``sim.servo``)
servo_stiffness     per joint (N m/rad), empty by default: a joint impedance servo instead,
                    K e + D de with D critically damped (``sim.servo.JointImpedanceServo``)
link_inertials      per named link, its mass m (kg), centre of mass c (m, link frame) and
                    inertia about c (kg m^2: Ixx, Iyy, Izz, Ixy, Ixz, Iyz): replace the URDF's
                    inertial (an identified model's links)
==================  ===========================================================================

Sensor keys (``sim.sensor.apply_sensor``) act on the logged signals after the simulation, not on
the physics: ``sensor_delay`` (control periods, dq and tau late), ``sensor_velocity_scale``
(logged dq / true dq), ``sensor_torque_offset`` (N m per joint, added to tau) and
``sensor_velocity_filter`` (s, time constant of a first-order low-pass on dq) and
``sensor_joint_velocity_scale`` (one value per joint, logged dq / true dq per joint, on top of the
global scale) and ``sensor_velocity_step`` (rad/s per joint, 0: none: the logged dq rounded to a
multiple of that step, an encoder-based velocity; applied after the encoder noise,
``sim.sensor.quantised_velocity``). The defaults are a perfect sensor.

The per-joint vectors (``PER_JOINT``) have one value per joint of the robot the plant is applied
to; left empty, they hold the nominal value at every joint (``PlantParameters.for_joints``).

Plant parameters are simulation truth: a dataset never records them (``controller.measured.dataset``).

Built-in plants (``plant_named``, files in ``sim/plants/``): ``identified_panda``, the Panda as
identified from measured data by Gaz et al. (RA-L 2019). Its link inertials are the URDF's
already (example-robot-data's Panda carries them), so the file adds their joint friction: the
sigmoid tau_f = phi_1 / (1 + exp(-phi_2 (dq + phi_3))) - (its value at dq = 0) as a dry
friction of half its range, phi_1 / 2, per joint (MuJoCo's friction loss is symmetric: the
offset phi_3, a few hundredths of a rad/s, is left out).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np

from impactqp.controller.measured.atomic import write_text_atomic
from impactqp.controller.model.files import read_mapping
from impactqp.controller.model.robot_description import RobotDescription
from impactqp.controller.model.tool_description import ToolDescription
from impactqp.controller.model.validation import BadInputError, finite_vector, number_in_range, vector_in_range

PLANTS_DIRECTORY = Path(__file__).parent / "plants"
"""The built-in plant files, ``<name>.json``."""

DEFAULT_SOLREF = (0.007, 1.0)
DEFAULT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
DEFAULT_SERVO_GAIN = 5.0


class PlantParameterError(BadInputError):
    """A plant parameter (or a plant-parameter file) that cannot be used."""


RANGES = {
    "armature": (0.0, 10.0, "kg m^2"),
    "joint_damping": (0.0, 500.0, "N m s/rad"),
    "joint_friction": (0.0, 50.0, "N m"),
    "payload_mass": (0.0, 5.0, "kg"),
    "payload_com": (-0.5, 0.5, "m"),
    "friction": (0.0, 2.0, ""),
    "servo_gain": (0.1, 1000.0, "rad/s"),
    "servo_stiffness": (1.0, 1e5, "N m/rad"),
    "sensor_delay": (0.0, 50.0, "control periods"),
    "sensor_velocity_scale": (0.5, 2.0, ""),
    "sensor_torque_offset": (-20.0, 20.0, "N m"),
    "sensor_velocity_filter": (0.0, 0.1, "s"),
    "sensor_joint_velocity_scale": (0.5, 2.0, ""),
    "sensor_velocity_step": (0.0, 0.1, "rad/s"),
}
"""Physical ranges of the plant parameters (per entry of a vector): reflected rotor inertias and
viscous damping well above a Panda's (the diagnosis fits up to 5 kg m^2 and 200 N m s/rad), dry
joint friction up to the torque of a Panda's small joints (12 N m) and more, a
payload within the Panda's 3 kg rating plus margin (the fit's 5 kg) with its centre of mass
within half a metre of the tool tip, a Coulomb coefficient up to 2 (``postures.MAX_FRICTION``),
a servo bandwidth up to 1000 rad/s (the 1 kHz loop), a joint stiffness up to 1e5 N m/rad (a
Franka's default joint impedance is 2000 to 3000 N m/rad); sensors up to 50 ms late, reading velocities
between half and twice the truth, torques off by at most 20 N m (a Panda's small joints carry
12 N m) and filtering dq with a time constant up to 0.1 s, and quantising dq to a step of at most 0.1 rad/s
(one count of a coarse encoder per control period)."""

PER_JOINT = {
    "armature": 0.0, "joint_damping": 0.0, "joint_friction": 0.0, "sensor_torque_offset": 0.0,
    "sensor_joint_velocity_scale": 1.0, "sensor_velocity_step": 0.0,
}
"""The per-joint vectors and their nominal value at each joint."""

LINK_INERTIAL_VALUES = 10
"""Numbers per link of ``link_inertials``: m, c (3), Ixx, Iyy, Izz, Ixy, Ixz, Iyz."""
MAX_LINK_MASS = 100.0  # kg

PAYLOAD_BODY = "payload"
"""The MuJoCo body of the payload (``apply_plant``)."""

MAX_SOLREF = (1.0, 10.0)
"""Largest contact time constant (s) and damping ratio of ``contact_solref``."""


@dataclass(frozen=True)
class PlantParameters:
    """Plant parameters (see the module docstring for units and effects); validated on creation."""

    armature: tuple[float, ...] = ()
    joint_damping: tuple[float, ...] = ()
    joint_friction: tuple[float, ...] = ()
    payload_mass: float = 0.0
    payload_com: tuple[float, ...] = (0.0, 0.0, 0.0)
    friction: float | None = None
    contact_solref: tuple[float, ...] = DEFAULT_SOLREF
    contact_solimp: tuple[float, ...] = DEFAULT_SOLIMP
    servo_gain: float = DEFAULT_SERVO_GAIN
    servo_stiffness: tuple[float, ...] = ()
    sensor_delay: float = 0.0
    sensor_velocity_scale: float = 1.0
    sensor_torque_offset: tuple[float, ...] = ()
    sensor_velocity_filter: float = 0.0
    sensor_joint_velocity_scale: tuple[float, ...] = ()
    sensor_velocity_step: tuple[float, ...] = ()
    link_inertials: tuple = ()

    def __post_init__(self):
        try:
            self._check()
        except PlantParameterError:
            raise
        except BadInputError as error:
            raise PlantParameterError(str(error)) from None

    def _check(self) -> None:
        """Each value within its physical range (``RANGES``, ``MAX_SOLREF``), stored as floats."""

        def set_(name, value):
            object.__setattr__(self, name, value)

        def vector(name: str, size: int | None) -> tuple[float, ...]:
            low, high, unit = RANGES[name]
            return tuple(vector_in_range(getattr(self, name), size, low, high, name, unit).tolist())

        def scalar(name: str) -> float:
            low, high, unit = RANGES[name]
            return number_in_range(getattr(self, name), low, high, name, unit)

        for name in PER_JOINT:
            set_(name, vector(name, None))
        sizes = {name: len(getattr(self, name)) for name in PER_JOINT if getattr(self, name)}
        if len(set(sizes.values())) > 1:
            given = ", ".join(f"{name} {size}" for name, size in sizes.items())
            raise PlantParameterError(f"the per-joint vectors must have one value per joint each, got {given}")
        set_("payload_com", vector("payload_com", 3))
        set_("payload_mass", scalar("payload_mass"))
        if self.friction is not None:
            set_("friction", scalar("friction"))
        solref = tuple(finite_vector(self.contact_solref, 2, "contact_solref").tolist())
        if not (0.0 < solref[0] <= MAX_SOLREF[0] and 0.0 < solref[1] <= MAX_SOLREF[1]):
            raise PlantParameterError(
                f"contact_solref = {list(solref)} must be (time constant in (0, {MAX_SOLREF[0]:g}] s, damping "
                f"ratio in (0, {MAX_SOLREF[1]:g}]); direct stiffness/damping (negative solref) is not supported"
            )
        set_("contact_solref", solref)
        solimp = tuple(finite_vector(self.contact_solimp, 5, "contact_solimp").tolist())
        dmin, dmax, width, midpoint, power = solimp
        if not (0.0 < dmin <= dmax < 1.0 and width > 0.0 and 0.0 < midpoint < 1.0 and power >= 1.0):
            raise PlantParameterError(
                f"contact_solimp = {list(solimp)} must satisfy 0 < dmin <= dmax < 1, width > 0, "
                "0 < midpoint < 1 and power >= 1"
            )
        set_("contact_solimp", solimp)
        set_("servo_gain", scalar("servo_gain"))
        set_("servo_stiffness", vector("servo_stiffness", None))
        set_("link_inertials", link_inertials(self.link_inertials))
        for name in ("sensor_delay", "sensor_velocity_scale", "sensor_velocity_filter"):
            set_(name, scalar(name))

    def for_joints(self, joints: int) -> "PlantParameters":
        """The same plant with ``joints`` values in every per-joint vector (``PER_JOINT``): the
        nominal value at every joint where it is left empty; a vector of another size is bad
        input."""
        filled = {}
        for name, nominal in PER_JOINT.items():
            values = getattr(self, name)
            if not values:
                filled[name] = (nominal,) * joints
            elif len(values) != joints:
                raise PlantParameterError(f"{name} must be {joints} numbers, got shape ({len(values)},)")
        if self.servo_stiffness and len(self.servo_stiffness) != joints:
            raise PlantParameterError(f"servo_stiffness must be {joints} numbers, got shape ({len(self.servo_stiffness)},)")
        return replace(self, **filled) if filled else self

    def physical(self) -> "PlantParameters":
        """The same plant with a perfect sensor: what the simulation itself needs (this plant
        itself when its sensor is perfect already). Made once per plant: a diagnosis asks it
        for every trial of every replay."""
        made = self.__dict__.get("_physical")
        if made is None:
            perfect = dict(
                sensor_delay=0.0, sensor_velocity_scale=1.0, sensor_torque_offset=(), sensor_velocity_filter=0.0,
                sensor_joint_velocity_scale=(), sensor_velocity_step=(),
            )
            same = all(getattr(self, name) == value for name, value in perfect.items())
            made = self if same else replace(self, **perfect)
            object.__setattr__(self, "_physical", made)  # not a field: equality and hash ignore it
        return made

    # ------------------------------------------------------------------ JSON
    @classmethod
    def from_dict(cls, values: dict) -> "PlantParameters":
        """Defaults overridden by ``values``; an unknown key is an error."""
        if not isinstance(values, dict):
            raise PlantParameterError(f"plant parameters must be a JSON object, got {type(values).__name__}")
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise PlantParameterError(
                f"unknown plant parameter(s) {', '.join(map(repr, unknown))}; known: {', '.join(known)}"
            )
        try:
            return cls(**values)
        except (TypeError, ValueError) as error:
            if isinstance(error, PlantParameterError):
                raise
            raise PlantParameterError(str(error)) from error

    @classmethod
    def from_json(cls, path: str | Path) -> "PlantParameters":
        path = Path(path)
        values = read_mapping(path, "plant parameter file", "json", PlantParameterError)
        try:
            return cls.from_dict(values)
        except BadInputError as error:  # the plant's own checks and the shared ones (a vector's length)
            raise PlantParameterError(f"{path}: {error}") from None

    @classmethod
    def named(cls, name: str) -> "PlantParameters":
        """The built-in plant ``name`` (module docstring); an unknown name is bad input."""
        names = built_in_plants()
        if name not in names:
            raise PlantParameterError(f"no built-in plant {name!r}; built-in: {', '.join(names)}")
        return cls.from_json(PLANTS_DIRECTORY / f"{name}.json")

    def to_dict(self) -> dict:
        values = asdict(self)
        values = {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()}
        values["link_inertials"] = {name: list(numbers) for name, numbers in self.link_inertials}
        return values

    def to_json(self, path: str | Path) -> None:
        """Write the parameters atomically (temporary file in the same directory + os.replace)."""
        write_text_atomic(Path(path), json.dumps(self.to_dict(), indent=2) + "\n")


def link_inertials(value) -> tuple:
    """``link_inertials`` as stored: ((link name, (m, cx, cy, cz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz)),
    ...) sorted by name, from that form or a mapping name -> 10 numbers (the JSON form). A mass in
    (0, ``MAX_LINK_MASS``] kg, a centre of mass within 1 m of the link frame, and an inertia about
    it that a body can have: positive definite, its principal moments meeting the triangle
    inequality."""
    items = value.items() if isinstance(value, dict) else value
    try:
        entries = [(name, numbers) for name, numbers in items]
    except (TypeError, ValueError):
        raise PlantParameterError("link_inertials must map link names to 10 numbers each") from None
    stored = []
    for name, numbers in entries:
        if not isinstance(name, str) or not name:
            raise PlantParameterError(f"link_inertials: a link name must be a non-empty string, got {name!r}")
        x = finite_vector(numbers, LINK_INERTIAL_VALUES, f"link_inertials[{name!r}]")
        mass, com, (ixx, iyy, izz, ixy, ixz, iyz) = x[0], x[1:4], x[4:]
        number_in_range(mass, 1e-9, MAX_LINK_MASS, f"the mass of link {name}", "kg")
        vector_in_range(com, 3, -1.0, 1.0, f"the centre of mass of link {name}", "m")
        inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        moments = np.linalg.eigvalsh(inertia)
        if moments[0] <= 0.0 or moments[2] > moments[0] + moments[1] * (1.0 + 1e-9):
            raise PlantParameterError(
                f"the inertia of link {name} (principal moments {np.round(moments, 9).tolist()} kg m^2) is not a "
                "body's: it must be positive definite with each moment at most the sum of the other two"
            )
        stored.append((name, tuple(float(v) for v in x)))
    names = [name for name, _ in stored]
    if len(set(names)) != len(names):
        raise PlantParameterError(f"link_inertials names a link twice: {names}")
    return tuple(sorted(stored))


def apply_plant(spec, mount, robot: RobotDescription, tool: ToolDescription, plant: PlantParameters) -> None:
    """The plant on the robot's MuJoCo spec before it is compiled (the module docstring's
    table): the drive armature, joint damping and dry friction of ``robot``'s joints, the
    payload (a point mass at ``tool``'s contact point on the body ``mount``, with its centre of
    mass offset) and the links' inertials. The plant's values replace the URDF's:
    franka_description's FR3 URDF declares <dynamics friction="0.2"/>, which MuJoCo would import
    as a friction loss the nominal plant does not have."""
    for name, armature, damping, friction in zip(robot.joints, plant.armature, plant.joint_damping, plant.joint_friction):
        joint = spec.joint(name)
        joint.armature = armature
        joint.damping = [damping, 0.0, 0.0]
        joint.frictionloss = friction
    if plant.payload_mass > 0.0:
        mount.add_body(
            name=PAYLOAD_BODY,
            pos=tool.contact_point.tolist(),
            mass=plant.payload_mass,
            ipos=list(plant.payload_com),
            inertia=[0.0, 0.0, 0.0],
            explicitinertial=True,
        )
    apply_link_inertials(spec, plant)


def apply_link_inertials(spec, plant: PlantParameters) -> None:
    """The plant's ``link_inertials`` on the bodies of a MuJoCo spec (before it is compiled); a
    link the robot does not have is bad input."""
    bodies = {body.name: body for body in spec.bodies}
    for name, values in plant.link_inertials:
        if name not in bodies:
            known = ", ".join(sorted(b for b in bodies if b and b != "world"))
            raise PlantParameterError(f"link_inertials: the robot has no link {name!r}; its links: {known}")
        body = bodies[name]
        body.mass, body.ipos = values[0], list(values[1:4])
        body.fullinertia = list(values[4:7]) + list(values[7:10])
        body.explicitinertial = True


def built_in_plants() -> list[str]:
    """The names of the built-in plants (``PlantParameters.named``)."""
    return sorted(path.stem for path in PLANTS_DIRECTORY.glob("*.json"))
