"""The MuJoCo scene of the standing G1 (docs/floating-base.md): the scene of ``sim.scene`` built
from its description (the same URDF as Pinocchio, the model's, its description's by default; the
collision meshes from the description's ``meshes``): a free joint on the pelvis (the floating
base), its own contact sphere of radius :data:`HAND_RADIUS` on the frame of the description's
``contact`` (the G1: on the forearm axis), a wall plane at x = ``wall_x`` facing the robot (normal
-x), and, the description having held contacts, a floor plane at z = 0 and the pairs of each held
contact's sole spheres with it, at that contact's ``friction``.

Contacts: condim 3, elliptic cones, solref :data:`CONTACT_SOLREF`, solimp :data:`CONTACT_SOLIMP`,
the wall's friction :data:`WALL_FRICTION` (the paper's mu); timestep 0.5 ms, implicitfast.

The plant's joints carry the G1's reflected rotor inertias (``controller.model.g1_actuators``,
MuJoCo's ``armature``: M -> M + diag(0, a)) unless told otherwise: the URDF has none, and a
geared robot's motors are a large part of what the hand's impact meets (the predictors keep the
URDF model, the paper's reason R3). ``armature=0`` gives the link-only plant.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.validation import number_in_range, vector_in_range

from .humanoid_feet import Soles
from .scene import (
    FLOOR_GEOM,
    WALL_GEOM,
    ContactParameters,
    Environment,
    MujocoScene,
    add_contact_geometry,
    add_environment,
    compile_spec,
    robot_spec,
)

TIMESTEP = 0.5e-3
WALL_FRICTION = 0.1123  # the paper's mu
CONTACT_SOLREF = (0.005, 1.0)
CONTACT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
WALL_HEIGHT = 1.0  # m: the wall plane's centre above the floor
WALL_SIZE = 1.0  # m: the wall's half-size
MAX_ARMATURE = 10.0  # kg m^2: the largest rotor inertia a joint may be given


@dataclass
class HumanoidScene(MujocoScene):
    """The standing robot's scene, with the ids the trials need: its contact sphere ``hand_geom``,
    the floor, the held contacts' bodies (``foot_bodies``) and ``soles``."""

    wall_x: float
    hand_geom: int
    floor_geom: int
    foot_bodies: tuple[int, ...]
    soles: Soles


def plant_armature(robot: RobotModel, armature=None) -> np.ndarray:
    """The rotor inertia (kg m^2) of each of the joints: the G1's actuators when ``armature`` is
    None, else one number for every joint or one per joint (0: the link-only plant)."""
    if armature is None:
        return joint_armature(robot.joint_names)
    n = len(robot.joint_names)
    if np.ndim(armature) == 0:
        return np.full(n, number_in_range(armature, 0.0, MAX_ARMATURE, "armature", "kg m^2"))
    return vector_in_range(armature, n, 0.0, MAX_ARMATURE, "armature", "kg m^2")


def build_humanoid_scene(
    robot: RobotModel, wall_x: float, *, timestep: float = TIMESTEP, armature=None
) -> HumanoidScene:
    """Compile the scene with the wall plane at x = ``wall_x`` (normal -x, towards the robot);
    ``armature`` is the joints' rotor inertia (:func:`plant_armature`: default the G1's actuators)."""
    rotor = plant_armature(robot, armature)
    description = robot.description
    spec = robot_spec(description, None, timestep, robot.urdf_path)
    contact = ContactParameters(WALL_FRICTION, CONTACT_SOLREF, CONTACT_SOLIMP)
    hand = add_contact_geometry(spec, description, None, contact)
    wall = Surface(np.array([wall_x, 0.0, WALL_HEIGHT]), np.array([-1.0, 0.0, 0.0]), WALL_FRICTION)
    add_environment(spec, description, hand, Environment(wall, contact, wall_size=WALL_SIZE, pair=""))
    hinges = [joint for joint in spec.joints if joint.type == mujoco.mjtJoint.mjJNT_HINGE]
    for joint in hinges:
        joint.armature = float(rotor[robot.joint_names.index(joint.name)])
    model = compile_spec(spec, description, robot.joint_names)
    feet = tuple(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, c.frame) for c in description.held_contacts)
    return HumanoidScene(
        model=model, data=mujoco.MjData(model),
        wall_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WALL_GEOM),
        base_nq=int(model.jnt_qposadr[1]), base_nv=int(model.jnt_dofadr[1]),  # the joints follow the free joint
        wall_x=wall_x, hand_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, hand),
        floor_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR_GEOM),
        foot_bodies=feet, soles=Soles.of(model, feet, tuple(c.friction for c in description.held_contacts)),
    )
