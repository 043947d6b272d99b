"""A render-only MuJoCo model of a scene: the robot's own meshes, its tool and the wall, for
pictures (``scenarios.video``), never for physics.

The simulated scenes (``sim.scene``) compile without any link geometry: every URDF collision
mesh gets contype = conaffinity = 0 and the compiler's ``discardvisual`` drops such geoms (the
inertias come from the URDF, so nothing physical depends on them). A render model is compiled
from the same spec (``sim.scene.robot_spec``, the contact geometry, the wall and, for a robot
that stands, the floor) with ``discardvisual`` off: the description's meshes (the Panda's and
the UR5's collision STLs of example-robot-data, the FR3's of franka_description, the G1's STLs)
stay as visual geoms of no collision, and a link whose URDF visual meshes MuJoCo can read (STL or
OBJ files in the description's mesh directory: the G1's) shows those instead
(:func:`add_visual_meshes`; the G1's collision elements are a few primitives and leave the
pelvis and the waist bare), and the boxes under the soles a stance raises (``sim.humanoid_scene.add_steps``,
the simulated scene's own). Its joints are the scene's, in the same order
(``sim.scene.compile_spec`` checks them), so its qpos layout equals the scene's and a trial's
logged configurations replay on it. A skybox, a light and (for an arm) a floor plane are added
for the eye; the plant (armature, damping, payload) is left out, it has no picture.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np

from impactqp.controller.model.postures import Surface
from impactqp.controller.model.files import read_text
from impactqp.controller.model.robot_description import RobotDescription, Stance, model_urdf
from impactqp.controller.model.tool_description import ToolDescription

from .humanoid_scene import add_steps
from .scene import (
    DEFAULT_TIMESTEP,
    FLOOR_GEOM,
    STANDING_SOLIMP,
    STANDING_SOLREF,
    STANDING_WALL_HEIGHT,
    STANDING_WALL_SIZE,
    WALL_FRICTION,
    ContactParameters,
    Environment,
    add_contact_geometry,
    add_environment,
    compile_spec,
    from_pinocchio,
    robot_spec,
)

LINK_RGBA = (0.82, 0.83, 0.86, 1.0)
FLOOR_RGBA = (0.60, 0.62, 0.66, 1.0)
READABLE_MESHES = (".stl", ".obj")  # the URDF mesh formats MuJoCo loads (not COLLADA's .dae)
ARM_FLOOR_SIZE = 1.0  # m: half-size of the arm's floor plane
# the contact's parameters do not show; these only let the shared builders add their geoms
SHOWN_CONTACT = ContactParameters(WALL_FRICTION, STANDING_SOLREF, STANDING_SOLIMP)


@dataclass(frozen=True)
class RenderScene:
    """A render model (module docstring), ``base_nq`` the free joint's qpos size (0 for a fixed
    base), the ``robot`` it shows and the wall's ``surface``."""

    model: mujoco.MjModel
    base_nq: int
    robot: RobotDescription
    surface: Surface

    def qpos(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo qpos of the Pinocchio configuration q (``sim.scene.from_pinocchio``)."""
        return from_pinocchio(q, self.base_nq) if self.base_nq else np.asarray(q, dtype=float)


def add_visual_meshes(spec: mujoco.MjSpec, robot: RobotDescription, urdf_text: str) -> None:
    """Give every link of ``urdf_text`` whose visual elements are all meshes MuJoCo reads (STL or
    OBJ, found in the description's mesh directory) those meshes, at their URDF origin (xyz,
    roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)) and scale, in place of its own geoms."""
    directory = robot.mesh_dir()
    for link in ET.fromstring(urdf_text).findall("link"):
        visuals = [(v, v.find("geometry/mesh")) for v in link.findall("visual")]
        files = [None if m is None else directory / m.get("filename").rsplit("/", 1)[-1] for _, m in visuals]
        body = spec.body(link.get("name"))
        if body is None or not files or not all(f is not None and f.suffix.lower() in READABLE_MESHES and f.is_file()
                                                for f in files):
            continue
        for geom in list(body.geoms):
            spec.delete(geom)
        for (visual, mesh), path in zip(visuals, files):
            name = f"visual_{link.get('name')}_{len(spec.meshes)}"
            scale = [float(x) for x in (mesh.get("scale") or "1 1 1").split()]
            spec.add_mesh(name=name, file=str(path), scale=scale)
            origin = visual.find("origin")
            xyz = [float(x) for x in ((origin.get("xyz") if origin is not None else None) or "0 0 0").split()]
            rpy = [float(x) for x in ((origin.get("rpy") if origin is not None else None) or "0 0 0").split()]
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, pos=xyz, quat=_quaternion(rpy),
                          rgba=list(LINK_RGBA), contype=0, conaffinity=0)


def _quaternion(rpy: list[float]) -> list[float]:
    """The unit quaternion (w, x, y, z) of the URDF roll-pitch-yaw angles."""
    roll, pitch, yaw = rpy
    quaternions = []
    for axis, angle in (((0.0, 0.0, 1.0), yaw), ((0.0, 1.0, 0.0), pitch), ((1.0, 0.0, 0.0), roll)):
        q = np.zeros(4)
        mujoco.mju_axisAngle2Quat(q, np.array(axis), angle)
        quaternions.append(q)
    result = np.zeros(4)
    mujoco.mju_mulQuat(result, quaternions[0], quaternions[1])
    mujoco.mju_mulQuat(result, result.copy(), quaternions[2])
    return result.tolist()


def _for_the_eye(spec: mujoco.MjSpec, floor: bool) -> None:
    """Keep the meshes (visual, no collision), colour the links, add a skybox, a light and, when
    asked, a floor plane at z = 0."""
    spec.compiler.discardvisual = False
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            geom.rgba = list(LINK_RGBA)
        elif geom.name == FLOOR_GEOM:
            geom.rgba = list(FLOOR_RGBA)
    spec.add_texture(
        name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.93, 0.95, 0.98], rgb2=[0.62, 0.68, 0.76], width=64, height=64,
    )
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    spec.worldbody.add_light(
        pos=[0.0, 0.0, 3.0], dir=[0.3, 0.2, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, diffuse=[0.6, 0.6, 0.6],
    )
    if floor:
        size = ARM_FLOOR_SIZE
        spec.worldbody.add_geom(
            name=FLOOR_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[size, size, 0.01], rgba=list(FLOOR_RGBA),
            contype=0, conaffinity=0,
        )


def arm_render_scene(robot: RobotDescription, tool: ToolDescription, surface: Surface) -> RenderScene:
    """The render model of a fixed-base arm's scene (``sim.scene.build_scene``) with ``tool``
    and the wall ``surface``."""
    spec = robot_spec(robot, tool, DEFAULT_TIMESTEP)
    add_visual_meshes(spec, robot, model_urdf(robot, tool))
    contact_geom = add_contact_geometry(spec, robot, tool, SHOWN_CONTACT)
    add_environment(spec, robot, contact_geom, Environment(surface, SHOWN_CONTACT, wall_size=0.5))
    _for_the_eye(spec, floor=True)
    return RenderScene(compile_spec(spec, robot, robot.joints), 0, robot, surface)


def humanoid_render_scene(
    robot: RobotDescription, joints: tuple[str, ...], wall_x: float, urdf_path=None, stance: Stance | None = None,
) -> RenderScene:
    """The render model of the standing robot's scene (``sim.humanoid_scene.build_humanoid_scene``) with
    the wall at x = ``wall_x``; ``joints`` are the model's joint names (after the free joint);
    ``stance``: a box under each sole it raises, as in the scene (None: the floor only)."""
    spec = robot_spec(robot, None, DEFAULT_TIMESTEP, urdf_path)
    add_visual_meshes(spec, robot, read_text(urdf_path or robot.urdf_path(), f"the {robot.name} URDF"))
    if stance is not None:
        add_steps(spec, robot, stance, SHOWN_CONTACT)
    hand = add_contact_geometry(spec, robot, None, SHOWN_CONTACT)
    surface = Surface(np.array([wall_x, 0.0, STANDING_WALL_HEIGHT]), np.array([-1.0, 0.0, 0.0]), WALL_FRICTION)
    add_environment(spec, robot, hand, Environment(surface, SHOWN_CONTACT, wall_size=STANDING_WALL_SIZE, pair=""))
    _for_the_eye(spec, floor=False)
    model = compile_spec(spec, robot, joints)
    return RenderScene(model, int(model.jnt_qposadr[1]), robot, surface)
