"""The MuJoCo scene of a robot: the same URDF and tool as Pinocchio, its contact geometry, a wall
and, for a robot that stands on held contacts, a floor. One builder for every robot description
(``controller.model.robot_description``); the fixed-base arm's scene is :func:`build_scene`, the
standing robot's ``sim.humanoid_scene.build_humanoid_scene`` (both a :class:`MujocoScene`).

The MuJoCo model is built in code from the URDF text that the Pinocchio model loads for a robot
and a tool (``robot_description.model_urdf``: the Panda of example-robot-data, franka_description's
FR3, the Franka Hand removed when the tool replaces it; a robot without a tool: its URDF as is),
with the edits of docs/simulation.md (:func:`mujoco_urdf`): the visual elements and the
``package://`` prefixes go (MuJoCo reads the STL collision meshes from the description's
``meshes``), the fingers are welded (their joints become fixed and the mimic coupling goes) and
inertias are taken exactly from the URDF (``inertiafromgeom`` false, ``balanceinertia`` false,
``fusestatic`` false). MuJoCo's joint-space inertia matrix then equals Pinocchio's to rounding
error.

Added in code (``mujoco.MjSpec``, :func:`robot_spec`, :func:`add_contact_geometry`,
:func:`add_environment`):

- a floating base (``base = "floating"``): a free joint on the URDF's root link, Pinocchio's free
  flyer up to two conventions converted by :func:`from_pinocchio` and :func:`to_pinocchio` (the
  quaternion is (w, x, y, z) instead of (x, y, z, w), and the base's linear velocity is in world
  axes instead of the base frame; the angular one is in the base frame in both);
- the contact geometry: the tool's (``controller.model.tool_description``), a sphere or a box pad,
  on the body of the frame it is fixed to, and, for a tool with a mass, a welded body ``tool``
  with its mass, centre of mass and inertia (so MuJoCo's M stays Pinocchio's); a robot without a
  tool: a massless sphere of radius :data:`HAND_RADIUS` on the frame of its ``contact`` whose far
  pole along that frame's x axis is the contact point;
- the wall: a MuJoCo plane through ``surface.point`` whose z axis is ``surface.normal``
  (the solid half-space lies behind the plane, away from the robot);
- with held contacts (a standing robot's soles): a floor plane at z = 0 and, for a stance that
  puts a held contact on a raised surface (``Stance.heights``), a box (a step, ``sim.humanoid_scene.STEP_SIZE``)
  under that sole whose top is the surface;
- explicit contact pairs: the contact geometry with the wall and, with held contacts, the sole
  spheres (from the URDF) of each held contact's frame with the floor (and its step) at that
  contact's ``friction``. Every geom has contype = conaffinity = 0, so the pairs are the only contacts of
  the scene; condim, friction, solref and solimp are set on the pairs and on their geoms;
- the arm's plant (:func:`build_scene`): the drive armature, joint damping and, with a payload, a
  welded point-mass body ``payload`` on the hand (``sim.plant``).

The arm's physics defaults (the contact ones are ``sim.plant`` defaults; the standing robot's:
below the table):

====================  =====================  =================================================
option                default                why
====================  =====================  =================================================
timestep              0.25 ms                four substeps per 1 ms control period; the soft
                                             contact needs timestep <= solref[0] / 2
integrator            implicitfast           stable with stiff joint damping and armature
cone                  elliptic, condim 3     Coulomb cone of the paper's (24)
friction              0.1123                 the paper's mu (the surface's coefficient)
solref                (7 ms, 1.0)            a first contact phase (force above 1 N) about as
                                             long as the paper's ~15 ms (docs/results.md)
solimp                (0.95, 0.99, 1 mm,     stiff (d -> 0.99) once the tool is 1 mm deep
                      0.5, 2)
noslip_iterations     0 (MuJoCo's); the      MuJoCo's noslip post-processing (a projected
                      oblique study's scene  Gauss-Seidel pass after the main solver that
                      ``NOSLIP_ITERATIONS``  removes the soft model's slip in the friction
                                             dimensions): a contact inside its cone then
                                             sticks instead of creeping
====================  =====================  =================================================

Why the oblique study's scene has noslip (``build_scene(..., noslip_iterations=NOSLIP_ITERATIONS)``,
docs/frictional-impacts.md, "Creep is not slip"): the study reads the contact's mode against
Coulomb's law, whose stick is a tangential velocity of zero. MuJoCo's soft friction lets a
contact inside its cone creep at a speed that grows with the force pressing it (a stiff joint
impedance pushing the tool into the wall: 3.5 to 11.6 mm/s), so a stick of the physics reads as
a slip; noslip removes that creep and leaves a slide's v_t+ as it was (to 0.1 mm/s). The arm's
other simulations keep MuJoCo's default (0), bit for bit: what they measured (docs/results.md)
was measured on it, and none of them reads a contact's stick.

The standing robot's scene: ``sim.humanoid_scene``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from impactqp.controller.model.files import read_text
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot import TOOL_BODY
from impactqp.controller.model.robot_description import RobotDescription, model_urdf, robot_description
from impactqp.controller.model.tool_description import Pad, ToolDescription, tool_description
from impactqp.controller.model.validation import BadInputError

from .plant import PlantParameters, apply_plant

DEFAULT_TIMESTEP = 0.25e-3
TOOL_GEOM = "impact_tool"
HAND_GEOM = "hand_tool"
HAND_RADIUS = 0.02
WALL_GEOM = "wall"
FLOOR_GEOM = "floor"
FLOOR_SIZE = 2.0  # m: the floor plane's half-size
FREE_JOINT = "floating_base"
CONTACT_PAIR = "tool_wall"
CONTACT_CONDIM = 3
NO_COLLISION = dict(contype=0, conaffinity=0)  # every geom: only the explicit pairs collide
WALL_FRICTION = 0.1123  # the paper's mu
STANDING_SOLREF = (0.005, 1.0)
STANDING_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
STANDING_WALL_HEIGHT = 1.0  # m: the standing robot's wall plane's centre above the floor
STANDING_WALL_SIZE = 1.0  # m: that wall's half-size
NOSLIP_ITERATIONS = 10
"""MuJoCo's noslip iterations of the oblique study's scene (module docstring): 10 and 100 give the
same contact velocities to 0.01 mm/s on its sticking trials."""
MAX_NOSLIP_ITERATIONS = 1000


def mujoco_urdf(
    robot: str | RobotDescription = "panda",
    tool: str | Path | ToolDescription | None = "impact_tip",
    urdf_path: str | Path | None = None,
) -> str:
    """The robot's URDF for the tool (``model_urdf``; None: a robot without a tool, its URDF as
    is), edited for MuJoCo's importer (see the module docstring), as a string."""
    robot = robot_description(robot)
    if tool is None:
        text = read_text(urdf_path if urdf_path is not None else robot.urdf_path(), f"the {robot.name} URDF")
    else:
        text = model_urdf(robot, tool_description(tool), urdf_path)
    root = ET.fromstring(text)
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        mesh.set("filename", mesh.get("filename").rsplit("/", 1)[-1])
    for joint in root.findall("joint"):
        if joint.get("name") in robot.finger_joints:
            joint.set("type", "fixed")
            for tag in ("mimic", "limit", "dynamics", "axis"):
                for child in joint.findall(tag):
                    joint.remove(child)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension,
        "compiler",
        meshdir=str(robot.mesh_dir()),
        discardvisual="true",
        fusestatic="false",
        balanceinertia="false",
        inertiafromgeom="false",
        strippath="true",
    )
    return ET.tostring(root, encoding="unicode")


@dataclass(frozen=True)
class ContactParameters:
    """MuJoCo's soft contact of a pair and its geoms: Coulomb ``friction``, ``solref`` (time
    constant s, damping ratio), ``solimp`` (dmin, dmax, width m, midpoint, power), ``condim``."""

    friction: float
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    condim: int = CONTACT_CONDIM

    def geom(self, friction: float | None = None) -> dict:
        """The attributes of a geom of a pair (its friction, or ``friction``)."""
        mu = self.friction if friction is None else friction
        return dict(condim=self.condim, friction=[mu, 0.0, 0.0], solref=list(self.solref), solimp=list(self.solimp))

    def pair(self, friction: float | None = None) -> dict:
        """The attributes of a pair: isotropic tangential friction (its own, or ``friction``)."""
        mu = self.friction if friction is None else friction
        return {**self.geom(), "friction": [mu, mu, 0.0, 0.0, 0.0]}


def robot_spec(robot: RobotDescription, tool: ToolDescription | None, timestep: float, urdf_path=None) -> mujoco.MjSpec:
    """The robot's MuJoCo spec (module docstring): the edited URDF, the physics options
    (``timestep``, implicitfast, elliptic cones), a free joint on the root link of a floating
    base, and no geom colliding. A copy of the spec parsed once per description, tool, timestep
    and URDF (``shared_robot_spec``), which the caller may edit."""
    return shared_robot_spec(robot, tool, timestep, urdf_path).copy()


@lru_cache(maxsize=16)
def shared_robot_spec(robot: RobotDescription, tool: ToolDescription | None, timestep: float, urdf_path=None) -> mujoco.MjSpec:
    """``robot_spec``'s spec, parsed once and never edited: writing the URDF and parsing it cost
    as much as compiling the whole scene (a diagnosis builds one scene per fitted plant).
    Descriptions are immutable and compared by identity."""
    spec = mujoco.MjSpec.from_string(mujoco_urdf(robot, tool, urdf_path))
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    if robot.floating:
        spec.worldbody.first_body().add_freejoint(name=FREE_JOINT)
    for geom in spec.geoms:
        geom.contype = 0
        geom.conaffinity = 0
    return spec


def add_contact_geometry(
    spec, robot: RobotDescription, tool: ToolDescription | None, contact: ContactParameters
) -> str:
    """The geometry that hits the wall: the tool's, or the robot's own contact sphere (module
    docstring); returns its geom's name."""
    if tool is not None:
        _add_tool(spec.body(robot.frame_of(tool)), tool, contact.geom())
        return TOOL_GEOM
    own = robot.contact
    spec.body(own.frame).add_geom(
        name=HAND_GEOM, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[HAND_RADIUS, 0, 0],
        pos=(own.offset - [HAND_RADIUS, 0.0, 0.0]).tolist(), mass=0.0, **contact.geom(), **NO_COLLISION,
    )
    return HAND_GEOM


def _add_tool(mount, tool: ToolDescription, contact: dict) -> None:
    """The tool's contact geometry (a sphere or a box pad) on the body ``mount`` of its frame
    and, for a tool with a mass, a welded body ``tool`` carrying its mass, centre of mass and
    inertia (as principal moments and axes, which MuJoCo accepts for a point mass too)."""
    geometry = tool.geometry
    if isinstance(geometry, Pad):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, geometry.rotation.flatten())
        shape = dict(type=mujoco.mjtGeom.mjGEOM_BOX, size=(geometry.size / 2.0).tolist(), quat=quat.tolist())
    else:
        shape = dict(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[geometry.radius, 0.0, 0.0])
    mount.add_geom(
        name=TOOL_GEOM, pos=geometry.centre.tolist(), rgba=[0.9, 0.4, 0.1, 1.0], **NO_COLLISION, **shape, **contact,
    )
    if tool.mass > 0.0:
        moments, axes = np.linalg.eigh(tool.inertia)
        axes[:, 2] *= np.linalg.det(axes)  # a rotation: principal axes right-handed
        iquat = np.zeros(4)
        mujoco.mju_mat2Quat(iquat, axes.flatten())
        mount.add_body(
            name=TOOL_BODY, mass=tool.mass, ipos=tool.com.tolist(), iquat=iquat.tolist(),
            inertia=moments.tolist(), explicitinertial=True,
        )


@dataclass(frozen=True)
class Environment:
    """What the robot hits: the ``wall``'s pose, a square plane of half-size ``wall_size`` (m), the
    contact parameters of every pair (``contact``: the wall's friction; a held contact's pairs,
    its own) and the name of the contact geometry/wall pair (``pair``, "" for none)."""

    wall: Surface
    contact: ContactParameters
    wall_size: float
    pair: str = CONTACT_PAIR


def add_environment(spec, robot: RobotDescription, contact_geom: str, environment: Environment) -> None:
    """The wall and its pair with the contact geometry and, when the robot has held contacts, the
    floor and the pairs of each held contact's sole spheres with it (module docstring)."""
    contact, held = environment.contact, robot.held_contacts
    soles = {c.frame: [g for g in spec.body(c.frame).geoms if g.type == mujoco.mjtGeom.mjGEOM_SPHERE] for c in held}
    if held:
        # the floor's own friction is unused (each sole's pair sets its held contact's)
        size = FLOOR_SIZE
        spec.worldbody.add_geom(name=FLOOR_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[size, size, 0.01],
                                **contact.geom(max(c.friction for c in held)), **NO_COLLISION)
    wall, size = environment.wall, environment.wall_size
    wall_quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(wall_quat, wall.normal)
    spec.worldbody.add_geom(name=WALL_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[size, size, 0.01],
                            pos=list(wall.point), quat=list(wall_quat), rgba=[0.6, 0.6, 0.7, 0.5],
                            **contact.geom(), **NO_COLLISION)
    spec.add_pair(name=environment.pair, geomname1=contact_geom, geomname2=WALL_GEOM, **contact.pair())
    for c in held:
        for i, geom in enumerate(soles[c.frame]):
            geom.name = geom.name or f"{c.frame}_sole{i}"
            spec.add_pair(geomname1=geom.name, geomname2=FLOOR_GEOM, **contact.pair(c.friction))


def compile_spec(spec, robot: RobotDescription, joints) -> mujoco.MjModel:
    """The compiled model, whose joints after a floating base's free joint must be ``joints`` (the
    Pinocchio model's), in order."""
    model = spec.compile()
    names = [model.joint(i).name for i in range(model.njnt) if model.jnt_type[i] != mujoco.mjtJoint.mjJNT_FREE]
    if names != list(joints):
        raise RuntimeError(f"the MuJoCo {robot.name} must have exactly the model's joints {list(joints)}, in order")
    return model


@dataclass
class MujocoScene:
    """A compiled scene and its data: ``wall_geom`` the wall's geom id, ``base_nq`` and ``base_nv``
    the sizes of a floating base's free joint in qpos (position, quaternion) and qvel (twist),
    before the joints' (0 for a fixed base)."""

    model: mujoco.MjModel
    data: mujoco.MjData
    wall_geom: int
    base_nq: int
    base_nv: int

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def set_state(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Reset the simulation to the Pinocchio state (q, dq) (None: at rest) at t = 0 and run the
        forward pass."""
        mujoco.mj_resetData(self.model, self.data)
        if self.base_nq:
            self.data.qpos[:] = from_pinocchio(q, self.base_nq)
        else:
            self.data.qpos[:] = q
        if dq is not None:
            self.data.qvel[:] = dq
            if self.base_nv:  # the base's linear velocity from its frame into world axes
                R = np.empty(9)
                mujoco.mju_quat2Mat(R, self.data.qpos[3:self.base_nq])
                self.data.qvel[:3] = R.reshape(3, 3) @ dq[:3]
        mujoco.mj_forward(self.model, self.data)

    def mass_matrix(self) -> np.ndarray:
        """The joint-space inertia matrix M (with armature) of the current state, MuJoCo's velocity
        convention."""
        M = np.empty((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, M)
        return M


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


@dataclass
class Scene(MujocoScene):
    """The fixed-base arm's scene, with the ids the runner needs: ``tool_geom`` the tool's geom,
    ``surface`` the wall's pose, ``plant`` the plant parameters the model was built with,
    ``robot`` and ``tool`` the descriptions it was built from."""

    surface: Surface
    plant: PlantParameters
    tool_geom: int
    robot: RobotDescription
    tool: ToolDescription

    def tool_centre(self, q: np.ndarray | None = None) -> np.ndarray:
        """World position of the tool geometry's centre: in the current state, or at the joint
        positions q (computed on scratch data, the simulation state is left alone)."""
        if q is None:
            return self.data.geom_xpos[self.tool_geom].copy()
        data = mujoco.MjData(self.model)
        data.qpos[:] = q
        mujoco.mj_kinematics(self.model, data)
        return data.geom_xpos[self.tool_geom].copy()


def build_scene(
    surface: Surface = DEFAULT_WALL,
    plant: PlantParameters | None = None,
    *,
    timestep: float = DEFAULT_TIMESTEP,
    urdf_path: str | Path | None = None,
    robot: str | RobotDescription = "panda",
    tool: str | Path | ToolDescription = "impact_tip",
    noslip_iterations: int = 0,
) -> Scene:
    """Build and compile the fixed-base arm's scene: the robot from its URDF, the tool, the wall,
    the contact pair and the plant; ``noslip_iterations`` MuJoCo's noslip post-processing (0: off,
    MuJoCo's default; the oblique study's: ``NOSLIP_ITERATIONS``, module docstring)."""
    robot, tool = robot_description(robot), tool_description(tool)
    if isinstance(noslip_iterations, bool) or not isinstance(noslip_iterations, (int, np.integer)) or not (
            0 <= noslip_iterations <= MAX_NOSLIP_ITERATIONS):
        raise BadInputError(f"noslip_iterations = {noslip_iterations!r} must be an integer in [0, {MAX_NOSLIP_ITERATIONS}]")
    plant = (PlantParameters() if plant is None else plant).for_joints(len(robot.joints))
    if not (np.isfinite(timestep) and 0.0 < timestep <= 0.5e-3):
        raise BadInputError(f"timestep = {timestep} s must be in (0, 0.5 ms]")
    if plant.contact_solref[0] < 2.0 * timestep:
        raise BadInputError(
            f"contact_solref time constant {plant.contact_solref[0]} s must be at least twice the "
            f"timestep {timestep} s (MuJoCo would silently stiffen nothing below that)"
        )
    spec = robot_spec(robot, tool, timestep, urdf_path)
    spec.option.noslip_iterations = int(noslip_iterations)
    friction = surface.friction if plant.friction is None else plant.friction
    contact = ContactParameters(friction, tuple(plant.contact_solref), tuple(plant.contact_solimp))
    contact_geom = add_contact_geometry(spec, robot, tool, contact)
    add_environment(spec, robot, contact_geom, Environment(surface, contact, wall_size=0.5))
    apply_plant(spec, spec.body(robot.frame_of(tool)), robot, tool, plant)
    model = compile_spec(spec, robot, robot.joints)
    return Scene(
        model=model,
        data=mujoco.MjData(model),
        wall_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WALL_GEOM),
        base_nq=0,
        base_nv=0,
        surface=surface,
        plant=plant,
        tool_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, contact_geom),
        robot=robot,
        tool=tool,
    )
