"""The Unitree G1's actuators: reflected rotor inertia (armature) of each of its joints
(docs/floating-base.md, "The plant's actuators").

Each G1 joint is driven by one of four motors through a two-stage planetary gearbox. A rotor
stage spinning g times faster than the joint adds g^2 times its inertia to the joint's, so with
the stage inertias J1 (motor rotor), J2 (first planet stage), J3 (output stage) and the stage
ratios (1, g2, g3) the inertia reflected to the joint is

    armature = J1 (g2 g3)^2 + J2 g3^2 + J3.

The waist's pitch and roll and the ankles' pitch and roll are each driven by two 5020 motors
through a parallel linkage; near the standing posture each motor's rotor is reflected once,
so these joints get twice the 5020's armature.

The stage inertias and ratios are Unitree's published motor data (as collected in the MuJoCo
G1 model constants of the mjlab project). The URDF carries no rotor inertia: the predictors
keep the URDF model, the simulated plant adds these (the paper's reason R3).

The same data give the whole-body QP its joint acceleration limits (:func:`acceleration_limits`,
written into the description's ``[limits]``, docs/whole-body-qp.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .jump import constrained_inverse_inertia
from .validation import BadInputError


@dataclass(frozen=True)
class Motor:
    """A motor and its two-stage planetary gearbox: stage inertias (kg m^2) and stage ratios."""

    rotor_inertia: tuple[float, float, float]
    gear_ratio: tuple[float, float, float]

    @property
    def armature(self) -> float:
        """J1 (g2 g3)^2 + J2 g3^2 + J3 (kg m^2), the inertia reflected to the joint."""
        (j1, j2, j3), (_, g2, g3) = self.rotor_inertia, self.gear_ratio
        return j1 * (g2 * g3) ** 2 + j2 * g3**2 + j3


MOTORS = {
    "5020": Motor((0.139e-4, 0.017e-4, 0.169e-4), (1.0, 1.0 + 46.0 / 18.0, 1.0 + 56.0 / 16.0)),
    "7520-14": Motor((0.489e-4, 0.098e-4, 0.533e-4), (1.0, 4.5, 1.0 + 48.0 / 22.0)),
    "7520-22": Motor((0.489e-4, 0.109e-4, 0.738e-4), (1.0, 4.5, 5.0)),
    "4010": Motor((0.068e-4, 0.0, 0.0), (1.0, 5.0, 5.0)),
}

# joint (without its left_/right_ prefix and _joint suffix) -> (motor, motors driving it)
JOINT_MOTORS = {
    "hip_pitch": ("7520-14", 1), "hip_yaw": ("7520-14", 1), "waist_yaw": ("7520-14", 1),
    "hip_roll": ("7520-22", 1), "knee": ("7520-22", 1),
    "shoulder_pitch": ("5020", 1), "shoulder_roll": ("5020", 1), "shoulder_yaw": ("5020", 1),
    "elbow": ("5020", 1), "wrist_roll": ("5020", 1),
    "wrist_pitch": ("4010", 1), "wrist_yaw": ("4010", 1),
    "waist_pitch": ("5020", 2), "waist_roll": ("5020", 2), "ankle_pitch": ("5020", 2), "ankle_roll": ("5020", 2),
}


def joint_kind(joint_name: str) -> str:
    """The key of :data:`JOINT_MOTORS` of a G1 joint name (``left_knee_joint`` -> ``knee``)."""
    kind = joint_name.removesuffix("_joint")
    for side in ("left_", "right_"):
        kind = kind.removeprefix(side)
    if kind not in JOINT_MOTORS:
        raise BadInputError(f"no G1 actuator drives the joint {joint_name!r}")
    return kind


def joint_armature(joint_names) -> np.ndarray:
    """The reflected rotor inertia (kg m^2) of each named G1 joint, in the given order."""
    armatures = []
    for name in joint_names:
        motor, count = JOINT_MOTORS[joint_kind(name)]
        armatures.append(count * MOTORS[motor].armature)
    return np.array(armatures)


TORQUE_SHARE = 0.5
"""The share of a joint's torque limit its acceleration limit may use: the rest is kept for
gravity and the coupling of the other joints."""
JERK_HORIZON = 0.0025
"""s: h = ddq_max / dddq_max, the jerk limit's time to swing the acceleration (the impact rows'
horizon, close to the Panda's 2 ms)."""


def acceleration_limits(robot, postures) -> np.ndarray:
    """ddq_max_i = share tau_max_i / (I_i + armature_i), the smallest over ``postures`` (the
    description's stances), I_i the larger of the joint's inertia with the base welded and every
    other joint locked (M_ii) and with the held contacts held and every other joint free
    (1 / P_ii, P the feet-held inverse inertia of ``jump.constrained_inverse_inertia``): an arm's
    joint moves its own links, a leg's the whole body pivoting on the feet."""
    armature = joint_armature(robot.description.joints)
    joints = slice(robot.base_nv, None)
    limits = []
    for q in postures:
        terms = robot.terms(q)
        inertia = np.maximum(np.diag(terms.M)[joints], 1.0 / np.diag(constrained_inverse_inertia(terms))[joints])
        limits.append(TORQUE_SHARE * robot.tau_max / (inertia + armature))
    return np.min(limits, axis=0)
