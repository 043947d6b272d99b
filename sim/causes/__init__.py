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
joint_friction dry joint friction torque per joint group       ``joint_friction`` (one per joint)
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

import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.tool_description import TOOLS, ToolDescription
from impactqp.controller.model.validation import name_in

from .cause import (
    GRID_POINTS,
    Cause,
    FixedParameters,
    JointGroupCause,
    group_means,
    group_name,
    joint_groups,
    payload_com,
    per_group,
)
from .plant_causes import (
    ArmatureCause,
    ContactCause,
    FrictionCause,
    JointDampingCause,
    JointFrictionCause,
    PayloadCause,
    ServoGainCause,
)
from .sensor_causes import (
    DelayCause,
    JointVelocityScaleCause,
    TorqueOffsetCause,
    VelocityFilterCause,
    VelocityScaleCause,
)

__all__ = [
    "Cause", "FixedParameters", "JointGroupCause", "joint_groups", "group_name", "GRID_POINTS", "per_group", "group_means", "payload_com",
    "ArmatureCause", "PayloadCause", "FrictionCause", "ContactCause", "JointDampingCause", "JointFrictionCause",
    "ServoGainCause",
    "DelayCause", "VelocityScaleCause", "JointVelocityScaleCause", "TorqueOffsetCause", "VelocityFilterCause",
    "default_causes", "CAUSE_NAMES", "SENSOR_CAUSE_NAMES", "PLANT_CAUSE_NAMES", "cause_named",
    "realistic_hidden_effect",
]


def default_causes(
    joints: int, surface_friction: float = DEFAULT_WALL.friction, tool: ToolDescription = TOOLS["impact_tip"]
) -> list[Cause]:
    """Every candidate cause, for a robot of ``joints`` joints and a surface of friction
    ``surface_friction`` hit with ``tool``."""
    return [
        ArmatureCause(joints),
        PayloadCause(tool),
        FrictionCause(surface_friction),
        ContactCause(),
        JointDampingCause(joints),
        JointFrictionCause(joints),
        ServoGainCause(),
        DelayCause(),
        VelocityScaleCause(joints),
        TorqueOffsetCause(joints),
        VelocityFilterCause(),
    ]


CAUSE_NAMES = tuple(
    kind.name for kind in (
        ArmatureCause, PayloadCause, FrictionCause, ContactCause, JointDampingCause, JointFrictionCause, ServoGainCause,
        DelayCause,
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
