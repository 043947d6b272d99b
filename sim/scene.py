"""The MuJoCo scene: the same robot URDF and tool as Pinocchio, and a wall.

The MuJoCo model is built in code from the URDF text that ``controller.model.robot.RobotModel``
loads for a robot and a tool (``robot_description.model_urdf``: the Panda of example-robot-data or
franka_description's FR3, the Franka Hand removed when the tool replaces it), with the edits of
docs/simulation.md: the visual elements and the ``package://`` prefixes go
(MuJoCo reads the STL collision meshes), the fingers are welded (their joints become fixed and
the mimic coupling goes) and inertias are taken exactly from the URDF (``inertiafromgeom``
false, ``balanceinertia`` false, ``fusestatic`` false). MuJoCo's joint-space inertia matrix
then equals Pinocchio's to rounding error.

Added in code (``mujoco.MjSpec``):

- the tool (``controller.model.tool_description``): its contact geometry, a sphere or a box pad,
  on the body of the frame it is fixed to, and, for a tool with a mass, a welded body ``tool``
  with its mass, centre of mass and inertia (so MuJoCo's M stays Pinocchio's);
- the wall: a MuJoCo plane through ``surface.point`` whose z axis is ``surface.normal``
  (the solid half-space lies behind the plane, away from the robot);
- one explicit contact pair tool/wall. Every geom has contype = conaffinity = 0, so the pair is
  the only contact of the scene; condim, friction, solref and solimp are set on the pair and on
  both of its geoms;
- with a payload, a welded point-mass body ``payload`` on the hand (``sim.plant``).

Physics defaults (the contact ones are ``sim.plant`` defaults):

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
====================  =====================  =================================================
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot import TOOL_BODY
from impactqp.controller.model.robot_description import RobotDescription, model_urdf, robot_description
from impactqp.controller.model.tool_description import Pad, ToolDescription, tool_description

from .plant import PlantParameters
from impactqp.controller.model.validation import BadInputError

DEFAULT_TIMESTEP = 0.25e-3
TOOL_GEOM = "impact_tool"
WALL_GEOM = "wall"
CONTACT_PAIR = "tool_wall"
PAYLOAD_BODY = "payload"
CONTACT_CONDIM = 3


def mujoco_urdf(
    robot: str | RobotDescription = "panda",
    tool: str | Path | ToolDescription = "impact_tip",
    urdf_path: str | Path | None = None,
) -> str:
    """The robot's URDF for the tool (``model_urdf``), edited for MuJoCo's importer (see the
    module docstring), as a string."""
    robot, tool = robot_description(robot), tool_description(tool)
    root = ET.fromstring(model_urdf(robot, tool, urdf_path))
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
        name=TOOL_GEOM, pos=geometry.centre.tolist(), contype=0, conaffinity=0, rgba=[0.9, 0.4, 0.1, 1.0],
        **shape, **contact,
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


@dataclass
class Scene:
    """A compiled scene and its data, with the ids the runner needs.

    ``surface`` is the wall's pose, ``plant`` the plant parameters the model was built with,
    ``robot`` and ``tool`` the descriptions it was built from.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    surface: Surface
    plant: PlantParameters
    tool_geom: int
    wall_geom: int
    robot: RobotDescription
    tool: ToolDescription

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def set_state(self, q: np.ndarray, dq: np.ndarray) -> None:
        """Reset the simulation to the joint state (q, dq) at t = 0 and run the forward pass."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q
        self.data.qvel[:] = dq
        mujoco.mj_forward(self.model, self.data)

    def mass_matrix(self) -> np.ndarray:
        """The joint-space inertia matrix M (with armature) of the current state."""
        M = np.empty((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, M)
        return M

    def tool_centre(self, q: np.ndarray | None = None) -> np.ndarray:
        """World position of the tool geometry's centre: in the current state, or at the joint
        positions q (computed on scratch data, the simulation state is left alone)."""
        if q is None:
            return self.data.geom_xpos[self.tool_geom].copy()
        data = mujoco.MjData(self.model)
        data.qpos[:] = q
        mujoco.mj_kinematics(self.model, data)
        return data.geom_xpos[self.tool_geom].copy()


def _add_wall(spec, surface: Surface, contact: dict, friction: float) -> None:
    """The wall plane and the tool/wall contact pair (the only pair that collides)."""
    wall_quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(wall_quat, surface.normal)
    spec.worldbody.add_geom(
        name=WALL_GEOM,
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0.5, 0.5, 0.01],
        pos=list(surface.point),
        quat=list(wall_quat),
        contype=0,
        conaffinity=0,
        rgba=[0.6, 0.6, 0.7, 0.5],
        **contact,
    )
    spec.add_pair(
        name=CONTACT_PAIR,
        geomname1=TOOL_GEOM,
        geomname2=WALL_GEOM,
        **{**contact, "friction": [friction, friction, 0.0, 0.0, 0.0]},
    )


def _apply_plant(spec, mount, robot: RobotDescription, tool: ToolDescription, plant: PlantParameters) -> None:
    """The plant's drive armature, joint damping and payload (a point mass at the contact point
    with its centre of mass offset) on the robot before it is compiled."""
    for name, armature, damping in zip(robot.joints, plant.armature, plant.joint_damping):
        joint = spec.joint(name)
        joint.armature = armature
        joint.damping = [damping, 0.0, 0.0]
        # the plant has no dry joint friction: franka_description's FR3 URDF declares
        # <dynamics friction="0.2"/>, which MuJoCo would import as a friction loss
        joint.frictionloss = 0.0
    if plant.payload_mass > 0.0:
        mount.add_body(
            name=PAYLOAD_BODY,
            pos=tool.contact_point.tolist(),
            mass=plant.payload_mass,
            ipos=list(plant.payload_com),
            inertia=[0.0, 0.0, 0.0],
            explicitinertial=True,
        )


def build_scene(
    surface: Surface = DEFAULT_WALL,
    plant: PlantParameters | None = None,
    *,
    timestep: float = DEFAULT_TIMESTEP,
    urdf_path: str | Path | None = None,
    robot: str | RobotDescription = "panda",
    tool: str | Path | ToolDescription = "impact_tip",
) -> Scene:
    """Build and compile the scene: the robot from its URDF, the tool, the wall, the contact pair
    and the plant."""
    robot, tool = robot_description(robot), tool_description(tool)
    plant = (PlantParameters() if plant is None else plant).for_joints(len(robot.joints))
    if not (np.isfinite(timestep) and 0.0 < timestep <= 0.5e-3):
        raise BadInputError(f"timestep = {timestep} s must be in (0, 0.5 ms]")
    if plant.contact_solref[0] < 2.0 * timestep:
        raise BadInputError(
            f"contact_solref time constant {plant.contact_solref[0]} s must be at least twice the "
            f"timestep {timestep} s (MuJoCo would silently stiffen nothing below that)"
        )
    spec = mujoco.MjSpec.from_string(mujoco_urdf(robot, tool, urdf_path))
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    for geom in spec.geoms:
        geom.contype = 0
        geom.conaffinity = 0

    friction = surface.friction if plant.friction is None else plant.friction
    contact = dict(
        condim=CONTACT_CONDIM,
        friction=[friction, 0.0, 0.0],
        solref=list(plant.contact_solref),
        solimp=list(plant.contact_solimp),
    )
    mount = spec.body(robot.frame_of(tool))
    _add_tool(mount, tool, contact)
    _add_wall(spec, surface, contact, friction)
    _apply_plant(spec, mount, robot, tool, plant)

    model = spec.compile()
    if tuple(model.joint(i).name for i in range(model.njnt)) != robot.joints:
        raise RuntimeError(f"the MuJoCo {robot.name} must have exactly the arm joints {robot.joints}, in order")
    data = mujoco.MjData(model)
    return Scene(
        model=model,
        data=data,
        surface=surface,
        plant=plant,
        tool_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TOOL_GEOM),
        wall_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WALL_GEOM),
        robot=robot,
        tool=tool,
    )
