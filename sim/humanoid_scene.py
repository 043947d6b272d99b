"""The standing robot's MuJoCo scene (:func:`build_humanoid_scene`, docs/floating-base.md), built
with the same parts as the arm's (``sim.scene``): its own contact sphere, a wall plane at
x = ``wall_x`` facing it (normal -x), the floor and the sole pairs, and a box under each sole a
stance raises (:func:`add_steps`); timestep 0.5 ms, solref ``STANDING_SOLREF``, solimp
``STANDING_SOLIMP``, the wall's friction ``WALL_FRICTION`` (the paper's mu) unless told otherwise. Its joints carry the
G1's reflected rotor inertias (``controller.model.g1_actuators``, MuJoCo's ``armature``:
M -> M + diag(0, a)) unless told otherwise (:func:`plant_armature`): the URDF has none, and a
geared robot's motors are a large part of what the hand's impact meets (the predictors keep the
URDF model, the paper's reason R3); ``armature=0`` gives the link-only plant.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import RobotDescription, Stance
from impactqp.controller.model.validation import number_in_range, vector_in_range

from .humanoid_feet import Soles
from .scene import (
    FLOOR_GEOM, NO_COLLISION, STANDING_SOLIMP, STANDING_SOLREF, STANDING_WALL_HEIGHT, STANDING_WALL_SIZE,
    WALL_FRICTION, WALL_GEOM, ContactParameters, Environment, MujocoScene, add_contact_geometry, add_environment,
    compile_spec, robot_spec,
)

STANDING_TIMESTEP = 0.5e-3
STEP_SIZE = (0.15, 0.08)  # m: a step's half-length (x) and half-width (y) about the sole's centre
MAX_ARMATURE = 10.0  # kg m^2: the largest rotor inertia a joint may be given


@dataclass
class HumanoidScene(MujocoScene):
    """The standing robot's scene, with the ids the trials need: its contact sphere ``hand_geom``,
    the floor, the held contacts' bodies (``foot_bodies``), ``soles`` and the steps under raised
    soles (``step_geoms``)."""

    wall_x: float
    hand_geom: int
    floor_geom: int
    foot_bodies: tuple[int, ...]
    soles: Soles
    step_geoms: tuple[int, ...] = ()

    @property
    def ground_geoms(self) -> tuple[int, ...]:
        """The geoms the soles stand on: the floor and the steps."""
        return (self.floor_geom, *self.step_geoms)


def plant_armature(robot: RobotModel, armature=None) -> np.ndarray:
    """The rotor inertia (kg m^2) of each of the joints: the G1's actuators when ``armature`` is
    None, else one number for every joint or one per joint (0: the link-only plant)."""
    if armature is None:
        return joint_armature(robot.joint_names)
    n = len(robot.joint_names)
    if np.ndim(armature) == 0:
        return np.full(n, number_in_range(armature, 0.0, MAX_ARMATURE, "armature", "kg m^2"))
    return vector_in_range(armature, n, 0.0, MAX_ARMATURE, "armature", "kg m^2")


def add_steps(spec, robot: RobotDescription, stance: Stance, contact: ContactParameters) -> tuple[str, ...]:
    """A box under each held contact the stance raises (its top at the stance's height, centred
    under the sole, half-sizes :data:`STEP_SIZE`) and the pairs of that sole's spheres with it;
    the boxes' names."""
    names = []
    for k, c in enumerate(robot.held_contacts):
        height = stance.height(k)
        if height == 0.0:
            continue
        name = f"step_{c.label}"
        centre = np.array(stance.feet[k]) + c.sole.mean(axis=0)
        spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[*STEP_SIZE, height / 2.0],
                                pos=[*centre, height / 2.0], rgba=[0.5, 0.45, 0.4, 1.0],
                                **contact.geom(c.friction), **NO_COLLISION)
        for geom in spec.body(c.frame).geoms:
            if geom.type == mujoco.mjtGeom.mjGEOM_SPHERE:
                spec.add_pair(geomname1=geom.name, geomname2=name, **contact.pair(c.friction))
        names.append(name)
    return tuple(names)


def build_humanoid_scene(
    robot: RobotModel, wall_x: float, *, timestep: float = STANDING_TIMESTEP, armature=None,
    stance: Stance | None = None, wall_friction: float = WALL_FRICTION,
) -> HumanoidScene:
    """Compile the standing robot's scene with the wall plane at x = ``wall_x`` (normal -x, towards
    the robot) of Coulomb coefficient ``wall_friction`` (the hand/wall pair's); ``armature`` is the
    joints' rotor inertia (:func:`plant_armature`: default the G1's actuators); ``stance``: a box
    under each sole it raises (:func:`add_steps`; None: the floor only)."""
    rotor = plant_armature(robot, armature)
    description = robot.description
    spec = robot_spec(description, None, timestep, robot.urdf_path)
    contact = ContactParameters(WALL_FRICTION, STANDING_SOLREF, STANDING_SOLIMP)
    wall_contact = ContactParameters(wall_friction, STANDING_SOLREF, STANDING_SOLIMP)
    hand = add_contact_geometry(spec, description, None, wall_contact)
    wall = Surface(np.array([wall_x, 0.0, STANDING_WALL_HEIGHT]), np.array([-1.0, 0.0, 0.0]), wall_friction)
    add_environment(spec, description, hand, Environment(wall, wall_contact, wall_size=STANDING_WALL_SIZE, pair=""))
    steps = () if stance is None else add_steps(spec, description, stance, contact)
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
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
        step_geoms=tuple(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name) for name in steps),
    )
