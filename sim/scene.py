"""The MuJoCo scene: the same example-robot-data Panda URDF as Pinocchio, a tool and a wall.

The MuJoCo model is built in code from the URDF file that ``controller.model.robot.PandaModel`` loads,
with the edits of docs/simulation.md: the visual elements and the ``package://`` prefixes go
(MuJoCo reads the STL collision meshes), the fingers are welded (their joints become fixed and
the mimic coupling goes) and inertias are taken exactly from the URDF (``inertiafromgeom``
false, ``balanceinertia`` false, ``fusestatic`` false). MuJoCo's joint-space inertia matrix
then equals Pinocchio's to rounding error.

Added in code (``mujoco.MjSpec``):

- the tool: a sphere of radius ``TOOL_RADIUS`` centred on the hand's z axis at
  ``TOOL_CENTRE_OFFSET`` (the massless contact tool of ``controller.model.robot``);
- the wall: a MuJoCo plane through ``surface.point`` whose z axis is ``surface.normal``
  (the solid half-space lies behind the plane, away from the robot);
- one explicit contact pair tool/wall. Every geom has contype = conaffinity = 0, so the pair is
  the only contact of the scene; condim, friction, solref and solimp are set on the pair and on
  both of its geoms;
- with a payload, a welded point-mass body ``payload`` on the hand (``sim.plant``).

Physics defaults (the contact ones are ``sim.plant`` defaults; measured on the named postures):

====================  =====================  =================================================
option                default                why
====================  =====================  =================================================
timestep              0.25 ms                four substeps per 1 ms control period; the soft
                                             contact needs timestep <= solref[0] / 2
integrator            implicitfast           stable with stiff joint damping and armature
cone                  elliptic, condim 3     Coulomb cone of the paper's (24)
friction              0.1123                 the paper's mu (the surface's coefficient)
solref                (7 ms, 1.0)            first contact phase 15-16 ms long (force above
                                             1 N), as the paper's ~15 ms
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
from impactqp.controller.model.robot import (
    FINGER_JOINTS,
    NQ,
    TOOL_CENTRE_OFFSET,
    TOOL_RADIUS,
    TOOL_TIP_OFFSET,
    panda_urdf_path,
)

from .plant import PlantParameters
from impactqp.controller.model.validation import BadInputError

DEFAULT_TIMESTEP = 0.25e-3
HAND_BODY = "panda_hand"
TOOL_GEOM = "impact_tool"
WALL_GEOM = "wall"
CONTACT_PAIR = "tool_wall"
PAYLOAD_BODY = "payload"
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, NQ + 1))
CONTACT_CONDIM = 3


def mujoco_urdf(urdf_path: str | Path | None = None) -> str:
    """The Panda URDF edited for MuJoCo's importer (see the module docstring), as a string."""
    urdf_path = Path(urdf_path) if urdf_path is not None else panda_urdf_path()
    root = ET.parse(urdf_path).getroot()
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        mesh.set("filename", mesh.get("filename").rsplit("/", 1)[-1])
    for joint in root.findall("joint"):
        if joint.get("name") in FINGER_JOINTS:
            joint.set("type", "fixed")
            for tag in ("mimic", "limit", "dynamics", "axis"):
                for child in joint.findall(tag):
                    joint.remove(child)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(
        extension,
        "compiler",
        meshdir=str(urdf_path.parent.parent / "meshes" / "collision"),
        discardvisual="true",
        fusestatic="false",
        balanceinertia="false",
        inertiafromgeom="false",
        strippath="true",
    )
    return ET.tostring(root, encoding="unicode")


@dataclass
class Scene:
    """A compiled scene and its data, with the ids the runner needs.

    ``surface`` is the wall's pose, ``plant`` the plant parameters the model was built with.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    surface: Surface
    plant: PlantParameters
    tool_geom: int
    wall_geom: int

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
        M = np.empty((NQ, NQ))
        mujoco.mj_fullM(self.model, self.data, M)
        return M

    def tool_centre(self, q: np.ndarray | None = None) -> np.ndarray:
        """World position of the tool sphere's centre: in the current state, or at the joint
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
) -> Scene:
    """Build and compile the scene: Panda from the URDF, tool, wall, contact pair and plant."""
    plant = PlantParameters() if plant is None else plant
    if not (np.isfinite(timestep) and 0.0 < timestep <= 0.5e-3):
        raise BadInputError(f"timestep = {timestep} s must be in (0, 0.5 ms]")
    if plant.contact_solref[0] < 2.0 * timestep:
        raise BadInputError(
            f"contact_solref time constant {plant.contact_solref[0]} s must be at least twice the "
            f"timestep {timestep} s (MuJoCo would silently stiffen nothing below that)"
        )
    spec = mujoco.MjSpec.from_string(mujoco_urdf(urdf_path))
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
    hand = spec.body(HAND_BODY)
    hand.add_geom(
        name=TOOL_GEOM,
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[TOOL_RADIUS, 0.0, 0.0],
        pos=[0.0, 0.0, TOOL_CENTRE_OFFSET],
        contype=0,
        conaffinity=0,
        rgba=[0.9, 0.4, 0.1, 1.0],
        **contact,
    )
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

    for name, armature, damping in zip(ARM_JOINTS, plant.armature, plant.joint_damping):
        joint = spec.joint(name)
        joint.armature = armature
        joint.damping = [damping, 0.0, 0.0]
    if plant.payload_mass > 0.0:
        hand.add_body(
            name=PAYLOAD_BODY,
            pos=[0.0, 0.0, TOOL_TIP_OFFSET],
            mass=plant.payload_mass,
            ipos=list(plant.payload_com),
            inertia=[0.0, 0.0, 0.0],
            explicitinertial=True,
        )

    model = spec.compile()
    if tuple(model.joint(i).name for i in range(model.njnt)) != ARM_JOINTS:
        raise RuntimeError("the MuJoCo Panda must have exactly the seven arm joints, in order")
    data = mujoco.MjData(model)
    return Scene(
        model=model,
        data=data,
        surface=surface,
        plant=plant,
        tool_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TOOL_GEOM),
        wall_geom=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, WALL_GEOM),
    )
