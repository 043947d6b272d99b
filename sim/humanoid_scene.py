"""The MuJoCo scene of the standing G1: the same URDF as Pinocchio (the model's, its description's
by default; the collision meshes from the description's ``meshes``), a floor and a wall in
front of the right hand (docs/floating-base.md).

The URDF is edited for MuJoCo's importer as the Panda's (``sim.scene``): visuals and
``package://`` prefixes go, inertias are taken exactly from the URDF. Added in code
(``mujoco.MjSpec``): a free joint on the pelvis (the floating base), a floor plane at z = 0, a
wall plane at x = ``wall_x`` facing the robot (normal -x), a hand sphere of radius
:data:`HAND_RADIUS` fixed to the frame of the description's ``contact`` whose far pole along that
frame's x axis is the model's contact point (the G1: on the forearm axis), and explicit contact
pairs: the sole spheres (from the URDF) of each held contact's frame with the floor, at that
contact's ``friction``, the hand sphere with the wall. Every other geom has contype =
conaffinity = 0.

The plant's joints carry the G1's reflected rotor inertias (``controller.model.g1_actuators``,
MuJoCo's ``armature``: M -> M + diag(0, a)) unless told otherwise: the URDF has none, and a
geared robot's motors are a large part of what the hand's impact meets (the predictors keep the
URDF model, the paper's reason R3). ``armature=0`` gives the link-only plant.

MuJoCo's free joint differs from Pinocchio's free-flyer in two conventions, converted by
:func:`to_pinocchio`: the quaternion is (w, x, y, z) instead of (x, y, z, w), and the base's
linear velocity is in world axes instead of the base frame (the angular one is in the base frame
in both).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np

from impactqp.controller.model.floating_base import FloatingBaseModel
from impactqp.controller.model.g1_actuators import joint_armature
from impactqp.controller.model.validation import number_in_range, vector_in_range

from .humanoid_feet import Soles

TIMESTEP = 0.5e-3
HAND_RADIUS = 0.02
HAND_GEOM = "hand_tool"
WALL_GEOM = "wall"
FLOOR_GEOM = "floor"
BASE_BODY = "pelvis"
WALL_FRICTION = 0.1123  # the paper's mu
CONTACT_SOLREF = (0.005, 1.0)
CONTACT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
MAX_ARMATURE = 10.0  # kg m^2: the largest rotor inertia a joint may be given


def mujoco_urdf(robot: FloatingBaseModel) -> str:
    """The model's URDF edited for MuJoCo's importer (meshes from the description's directory),
    as a string."""
    root = ET.parse(robot.urdf_path).getroot()
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        mesh.set("filename", mesh.get("filename").rsplit("/", 1)[-1])
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension, "compiler", meshdir=str(robot.description.mesh_dir()), discardvisual="true",
        fusestatic="false", balanceinertia="false", inertiafromgeom="false", strippath="true",
    )
    return ET.tostring(root, encoding="unicode")


@dataclass
class HumanoidScene:
    """A compiled scene, its data and the ids the trials need. ``base_nq`` and ``base_nv`` are
    the sizes of the free joint in qpos (position, quaternion) and qvel (twist), before the
    joints'."""

    model: mujoco.MjModel
    data: mujoco.MjData
    wall_x: float
    hand_geom: int
    wall_geom: int
    floor_geom: int
    foot_bodies: tuple[int, int]
    soles: Soles
    base_nq: int
    base_nv: int

    def set_state(self, q_pin: np.ndarray) -> None:
        """Reset to the Pinocchio configuration q_pin at rest."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = from_pinocchio(q_pin, self.base_nq)
        mujoco.mj_forward(self.model, self.data)


def from_pinocchio(q: np.ndarray, base_nq: int) -> np.ndarray:
    """MuJoCo qpos from Pinocchio q, whose first ``base_nq`` coordinates are the free flyer's
    position and quaternion: quaternion (x, y, z, w) -> (w, x, y, z)."""
    quaternion = q[3:base_nq]
    return np.concatenate([q[:3], quaternion[-1:], quaternion[:-1], q[base_nq:]])


def to_pinocchio(qpos: np.ndarray, qvel: np.ndarray, base_nq: int) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio (q, v) from MuJoCo (qpos, qvel), whose first ``base_nq`` coordinates are the free
    joint's position and quaternion: quaternion reordered, the base's linear velocity turned from
    world axes into the base frame."""
    quaternion = qpos[3:base_nq]  # w, x, y, z
    q = np.concatenate([qpos[:3], quaternion[1:], quaternion[:1], qpos[base_nq:]])
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, quaternion)
    v = qvel.copy()
    v[:3] = R.reshape(3, 3).T @ qvel[:3]
    return q, v


def plant_armature(robot: FloatingBaseModel, armature=None) -> np.ndarray:
    """The rotor inertia (kg m^2) of each of the joints: the G1's actuators when ``armature`` is
    None, else one number for every joint or one per joint (0: the link-only plant)."""
    if armature is None:
        return joint_armature(robot.joint_names)
    n = len(robot.joint_names)
    if np.ndim(armature) == 0:
        return np.full(n, number_in_range(armature, 0.0, MAX_ARMATURE, "armature", "kg m^2"))
    return vector_in_range(armature, n, 0.0, MAX_ARMATURE, "armature", "kg m^2")


def build_humanoid_scene(
    robot: FloatingBaseModel, wall_x: float, *, timestep: float = TIMESTEP, armature=None
) -> HumanoidScene:
    """Compile the scene with the wall plane at x = ``wall_x`` (normal -x, towards the robot);
    ``armature`` is the joints' rotor inertia (:func:`plant_armature`: default the G1's actuators)."""
    rotor = plant_armature(robot, armature)
    spec = mujoco.MjSpec.from_string(mujoco_urdf(robot))
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.body(BASE_BODY).add_freejoint(name="floating_base")
    contacts = robot.description.held_contacts
    soles = {c.frame: [g for g in spec.body(c.frame).geoms if g.type == mujoco.mjtGeom.mjGEOM_SPHERE] for c in contacts}
    for geom in spec.geoms:
        geom.contype = 0
        geom.conaffinity = 0
    common = dict(condim=3, solref=list(CONTACT_SOLREF), solimp=list(CONTACT_SOLIMP), contype=0, conaffinity=0)
    # the floor's own friction is unused (each sole's pair below sets its held contact's)
    floor_friction = max(c.friction for c in contacts)
    spec.worldbody.add_geom(name=FLOOR_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2.0, 2.0, 0.01],
                            friction=[floor_friction, 0.0, 0.0], **common)
    wall_quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(wall_quat, np.array([-1.0, 0.0, 0.0]))
    spec.worldbody.add_geom(name=WALL_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1.0, 1.0, 0.01],
                            pos=[wall_x, 0.0, 1.0], quat=list(wall_quat), rgba=[0.6, 0.6, 0.7, 0.5],
                            friction=[WALL_FRICTION, 0.0, 0.0], **common)
    contact = robot.description.contact
    spec.body(contact.frame).add_geom(name=HAND_GEOM, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[HAND_RADIUS, 0, 0],
                                      pos=(contact.offset - [HAND_RADIUS, 0.0, 0.0]).tolist(), mass=0.0,
                                      friction=[WALL_FRICTION, 0.0, 0.0], **common)
    pair = dict(condim=3, solref=list(CONTACT_SOLREF), solimp=list(CONTACT_SOLIMP))
    spec.add_pair(geomname1=HAND_GEOM, geomname2=WALL_GEOM, friction=[WALL_FRICTION, WALL_FRICTION, 0, 0, 0], **pair)
    for held in contacts:
        for i, geom in enumerate(soles[held.frame]):
            geom.name = geom.name or f"{held.frame}_sole{i}"
            spec.add_pair(geomname1=geom.name, geomname2=FLOOR_GEOM,
                          friction=[held.friction, held.friction, 0, 0, 0], **pair)
    hinges = [joint for joint in spec.joints if joint.type == mujoco.mjtJoint.mjJNT_HINGE]
    for joint in hinges:
        joint.armature = float(rotor[robot.joint_names.index(joint.name)])
    model = spec.compile()
    names = [model.joint(i).name for i in range(1, model.njnt)]
    if names != robot.joint_names:
        raise RuntimeError("the MuJoCo G1 must have the Pinocchio model's joints, in order")
    feet = tuple(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, c.frame) for c in contacts)
    return HumanoidScene(
        model=model, data=mujoco.MjData(model), wall_x=wall_x,
        hand_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, HAND_GEOM),
        wall_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WALL_GEOM),
        floor_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR_GEOM),
        foot_bodies=feet, soles=Soles.of(model, feet, tuple(c.friction for c in contacts)),
        base_nq=int(model.jnt_qposadr[1]), base_nv=int(model.jnt_dofadr[1]),  # the joints follow the free joint
    )
