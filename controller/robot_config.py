"""The ``[libfranka]`` table of the controller configuration: the connected robot's own settings
(collision reflex, joint impedance, load, post-reflex policy, model check), which the ``franka``
and ``panda`` backends apply on connect (``docs/robot-loop.md``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .model import validation
from .model.validation import BadInputError

MAX_COLLISION_TORQUE, MAX_COLLISION_FORCE = 1000.0, 1000.0
"""N m, N: collision-reflex thresholds far above the joints' torque limits (87 N m) still name a
torque; a larger number is a typing error."""

MAX_JOINT_STIFFNESS = 14250.0
"""N m/rad: the stiffness range of the Franka joint-impedance controller (libfranka's
``setJointImpedance``)."""

MAX_LOAD_MASS, MAX_LOAD_OFFSET, MAX_LOAD_INERTIA = 3.0, 1.0, 1.0
"""kg, m, kg m^2: the Panda and the FR3 carry at most 3 kg; the load's centre of mass and
inertia belong to a hand-held tool."""

MAX_MODEL_DIFFERENCE = 1.0

DEFAULT_TORQUE_THRESHOLDS = [100.0] * 4 + [20.0] * 3
"""N m: the joint collision thresholds of the Franka arms unless the table or the impact sets
others, above the impulsive torques the impact-aware constraints allow (tau_max = 87/12 N m)."""
DEFAULT_FORCE_THRESHOLDS = [100.0] * 3 + [30.0] * 3
"""N, N m: the Cartesian collision thresholds (force, then moment) unless the table or the impact
sets others."""

FROM_IMPACT, FIXED = "from_impact", "fixed"
COLLISION_CHOICES = (FROM_IMPACT, FIXED)
IMPACT_THRESHOLD_FACTOR = 3.0
"""The safety factor k of the thresholds over the predicted peaks (``collision_thresholds``): a
contact force pulse peaks above its mean over delta_t (pi/2 times it for a half sine), and the
surface's stiffness and the model's error add to it."""
MAX_THRESHOLD_FACTOR = 10.0
"""The largest factor the table accepts: ten times the predicted peak is no longer a threshold
for the planned impact."""

JOINT_SETTINGS = ("lower_torque_thresholds", "upper_torque_thresholds", "joint_impedance")
"""The settings with one value per joint of the robot (``RobotConfig.check_joints``)."""


@dataclass
class RobotConfig:
    """The connected robot's own settings (``franka`` and ``panda`` backends; ``docs/robot-loop.md``).

    The collision-reflex thresholds (``Robot.set_collision_behavior``: torques per joint in N m,
    Cartesian force/torque in N and N m): with ``collision_thresholds`` "from_impact" (default) a
    run sets them from its predicted impact, ``impact_threshold_factor`` times the peak joint
    torques and contact wrench, never below the defaults (``DEFAULT_TORQUE_THRESHOLDS``,
    ``DEFAULT_FORCE_THRESHOLDS``; ``controller.runtime.collision_thresholds``); with "fixed" they
    are the four lists. A list given (not None) wins in both cases; one left out is the default
    ("fixed") or the computed one. The factory values trip on an impact on purpose.
    ``joint_impedance`` is the stiffness of the robot's joint controller (N m/rad, libfranka's
    default). ``load_mass`` (kg), ``load_com`` (m, flange frame) and ``load_inertia`` (kg m^2, 3x3
    column-major, about the centre of mass) are the load ``Robot.set_load`` gets; each one left
    out (None) is the declared tool's (``ToolDescription``: its mass, centre of mass and inertia
    expressed in the flange frame, ``libfranka_robot.declared_load``). After a
    reflex the run ends; ``automatic_error_recovery`` then clears the robot's error state. On
    connect the robot's mass matrix M_r at the current state is compared with ours, M:
    ||M_r - M||_F / ||M_r||_F above ``max_model_difference`` refuses the robot.
    """

    collision_thresholds: str = FROM_IMPACT
    impact_threshold_factor: float = IMPACT_THRESHOLD_FACTOR
    lower_torque_thresholds: list[float] | None = None
    upper_torque_thresholds: list[float] | None = None
    lower_force_thresholds: list[float] | None = None
    upper_force_thresholds: list[float] | None = None
    joint_impedance: list[float] = field(default_factory=lambda: [3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    load_mass: float | None = None
    load_com: list[float] | None = None
    load_inertia: list[float] | None = None
    automatic_error_recovery: bool = False
    max_model_difference: float = 0.02

    def __post_init__(self):
        validation.name_in(self.collision_thresholds, COLLISION_CHOICES, "libfranka.collision_thresholds")
        validation.number_in_range(
            self.impact_threshold_factor, 1.0, MAX_THRESHOLD_FACTOR, "libfranka.impact_threshold_factor",
            "(times the predicted peak)",
        )
        for kind, size, high in (("torque", None, MAX_COLLISION_TORQUE), ("force", 6, MAX_COLLISION_FORCE)):
            lower, upper = (
                None if getattr(self, name) is None else validation.positive_vector(getattr(self, name), size, f"libfranka.{name}", high)
                for name in (f"lower_{kind}_thresholds", f"upper_{kind}_thresholds")
            )
            if lower is not None and upper is not None:
                if lower.shape != upper.shape:
                    raise BadInputError(
                        f"libfranka.lower_{kind}_thresholds and libfranka.upper_{kind}_thresholds must have as many values"
                    )
                if np.any(lower > upper):
                    raise BadInputError(f"libfranka.lower_{kind}_thresholds must not exceed libfranka.upper_{kind}_thresholds")
            for side, values in (("lower", lower), ("upper", upper)):
                setattr(self, f"{side}_{kind}_thresholds", None if values is None else values.tolist())
        self.joint_impedance = validation.positive_vector(
            self.joint_impedance, None, "libfranka.joint_impedance", MAX_JOINT_STIFFNESS
        ).tolist()
        if self.load_mass is not None:
            validation.number_in_range(self.load_mass, 0.0, MAX_LOAD_MASS, "libfranka.load_mass", "kg")
        if self.load_com is not None:
            com = validation.finite_vector(self.load_com, 3, "libfranka.load_com")
            if np.max(np.abs(com)) > MAX_LOAD_OFFSET:
                raise BadInputError(f"libfranka.load_com {com.tolist()} must lie within {MAX_LOAD_OFFSET:g} m of the flange")
            self.load_com = com.tolist()
        if self.load_inertia is not None:
            inertia = validation.finite_vector(self.load_inertia, 9, "libfranka.load_inertia").reshape(3, 3)
            if not np.allclose(inertia, inertia.T) or np.min(np.linalg.eigvalsh(inertia)) < -1e-12:
                raise BadInputError("libfranka.load_inertia must be a symmetric positive semi-definite 3x3 matrix")
            if np.max(np.abs(inertia)) > MAX_LOAD_INERTIA:
                raise BadInputError(f"libfranka.load_inertia entries must stay below {MAX_LOAD_INERTIA:g} kg m^2")
            self.load_inertia = inertia.ravel().tolist()
        validation.boolean(self.automatic_error_recovery, "libfranka.automatic_error_recovery")
        validation.number_in_range(
            self.max_model_difference, 0.0, MAX_MODEL_DIFFERENCE, "libfranka.max_model_difference",
            "(relative difference of the mass matrices)", low_open=True,
        )

    def check_joints(self, joints: int) -> None:
        """Bad input unless every per-joint setting (``JOINT_SETTINGS``) has one value for each of
        the robot's ``joints`` joints."""
        for name in JOINT_SETTINGS:
            if getattr(self, name) is not None:
                validation.finite_vector(getattr(self, name), joints, f"libfranka.{name}")

