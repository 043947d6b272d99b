"""The soles' measured contact state: what the closed form's foot criteria predict, read from
MuJoCo's per-contact forces of the sole spheres (docs/floating-base.md, "Measured onsets").

Each foot touches the floor with the spheres of its sole (four on the G1). At every physics step
and for each foot, from the contacts of its spheres:

- ``load``: the foot's normal ground force f_n (N), the sum over its spheres;
- ``cone``: |f_t| / (mu f_n) of the foot's summed ground force (f_t its horizontal part): the
  summed force is on the friction cone at 1, as in the closed form's ``foot_slip``;
- ``margin``: the distance (m) of the foot's centre of pressure sum_i f_n,i p_i / f_n inside the
  nearest edge of the sole polygon (the convex hull of the sphere centres, in the foot's axes):
  0 when the spheres of one edge carry the whole load, as in the closed form's ``foot_lift``;
  -inf when the foot carries nothing;
- ``speed``: the largest horizontal speed (m/s) of a touching sphere's contact point, the foot
  body's velocity there.

Over a control step the step values are combined worst-first (:func:`worst`): the smallest load
and margin, the largest cone ratio and speed. Onsets (:func:`slip_onset`, :func:`lift_onset`):

- slip: cone >= 1 - :data:`CONE_TOLERANCE`, or speed > :data:`SLIP_SPEED`. MuJoCo's solver puts
  a sliding contact's force on the cone up to its tolerance, and a pushed, sticking soft contact
  creeps: 0.3 mm/s at 0.99 of the cone for a 20 kg sole (a test checks it stays below a tenth
  of SLIP_SPEED), while a sole pushed beyond the cone passes SLIP_SPEED within milliseconds.
  SLIP_SPEED (1 cm/s) thus separates creep from sliding by more than a decade on both sides.
- lift: margin <= :data:`LIFT_MARGIN` (1 mm): the spheres off that edge carry less than 2 % (across
  the 50-60 mm sole) or 0.6 % (along its 170 mm) of the foot's load, the centre of pressure is on
  the edge within the soft contact's resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from impactqp.controller.model.held_contact_description import convex_hull
from impactqp.controller.model.humanoid_stance import edge_normals

from .contact_force import contact_frame_forces, to_world

LOAD, CONE, MARGIN, SPEED = range(4)
CONE_TOLERANCE = 1e-3
SLIP_SPEED = 0.01  # m/s
LIFT_MARGIN = 1e-3  # m


@dataclass(frozen=True)
class Soles:
    """The feet of a scene: body ids, their sphere geoms, sole polygons (foot axes) and each
    foot's mu; for the compiled state (:func:`sole_states`), the foot of each geom of the model
    (``foot_index``, -1: not a sole sphere) and each sole's edges (``edges``, feet x k x 4: an
    edge's first vertex and its unit outward normal, a sole with fewer edges padded with copies
    of its first)."""

    bodies: tuple[int, ...]
    spheres: tuple[tuple[int, ...], ...]
    polygons: tuple[np.ndarray, ...]
    friction: tuple[float, ...]
    foot_index: np.ndarray
    edges: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, bodies, friction) -> Soles:
        """Every sphere geom of each foot body is a sole sphere; ``friction`` is one mu for every
        foot or one per foot."""
        spheres = tuple(
            tuple(g for g in range(model.ngeom) if model.geom_bodyid[g] == b and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE)
            for b in bodies
        )
        polygons = tuple(convex_hull(model.geom_pos[list(s), :2]) for s in spheres)
        foot_index = np.full(model.ngeom, -1, dtype=np.int64)
        for k, foot in enumerate(spheres):
            foot_index[list(foot)] = k
        edges = np.empty((len(polygons), max(len(p) for p in polygons), 4))
        for k, polygon in enumerate(polygons):
            table = np.hstack([polygon, edge_normals(polygon)])
            edges[k] = table[0]  # the padding: copies of the first edge
            edges[k, :len(polygon)] = table
        mu = tuple(float(f) for f in np.broadcast_to(np.asarray(friction, dtype=float), (len(spheres),)))
        return cls(tuple(bodies), spheres, polygons, mu, foot_index, edges)


ROTATION, POSITION, CENTRE, TWIST, FRICTION, FOOT_COLUMNS = 0, 9, 12, 15, 21, 22
"""The columns of a foot's row in :func:`sole_states`: its body's rotation (row-major), position,
centre of mass, velocity (angular, then linear, world axes, at the centre of mass) and mu."""


@njit(cache=True)
def sole_states(forces, frame, pos, geom, foot_index, feet, edges, state):
    """Kernel of :class:`SoleSensor` (module docstring): ``forces`` each contact's force in its
    contact frame (ncon x 3), ``frame``, ``pos`` and ``geom`` MuJoCo's contacts' frames,
    positions and geom pairs, ``feet`` one row per foot (``FOOT_COLUMNS``); writes ``state``
    (feet x 4)."""
    n = feet.shape[0]
    total = np.zeros((n, 6))  # per foot: the force (world), the normal force's moment (foot axes), the speed
    for c in range(forces.shape[0]):
        k = foot_index[geom[c, 0]]
        if k < 0:
            k = foot_index[geom[c, 1]]
        if k < 0:
            continue
        normal, t1, t2 = forces[c, 0], forces[c, 1], forces[c, 2]
        fx, fy, fz = to_world(frame, c, normal, t1, t2)
        sign = 1.0 if fz >= 0.0 else -1.0
        total[k, 0] += sign * fx
        total[k, 1] += sign * fy
        total[k, 2] += sign * fz
        for i in range(2):  # the contact point in the foot's axes
            local = 0.0
            for j in range(3):
                local += feet[k, ROTATION + 3 * j + i] * (pos[c, j] - feet[k, POSITION + j])
            total[k, 3 + i] += normal * local
        r = pos[c] - feet[k, CENTRE:CENTRE + 3]
        w, v = feet[k, TWIST:TWIST + 3], feet[k, TWIST + 3:TWIST + 6]
        vx = v[0] + (w[1] * r[2] - w[2] * r[1])
        vy = v[1] + (w[2] * r[0] - w[0] * r[2])
        total[k, 5] = max(total[k, 5], np.sqrt(vx * vx + vy * vy))
    for k in range(n):
        load = total[k, 2]
        state[k, LOAD], state[k, CONE], state[k, MARGIN], state[k, SPEED] = load, 0.0, -np.inf, total[k, 5]
        if load > 0.0:
            state[k, CONE] = np.sqrt(total[k, 0] ** 2 + total[k, 1] ** 2) / (feet[k, FRICTION] * load)
            x, y = total[k, 3] / load, total[k, 4] / load
            margin = np.inf
            for e in range(edges.shape[1]):
                margin = min(margin, edges[k, e, 2] * (edges[k, e, 0] - x) + edges[k, e, 3] * (edges[k, e, 1] - y))
            state[k, MARGIN] = margin


class SoleSensor:
    """The soles' states of a scene (module docstring), read after each physics step into
    buffers allocated once."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, soles: Soles):
        self.model, self.data, self.soles = model, data, soles
        n = len(soles.bodies)
        self._bodies = list(soles.bodies)
        self._feet = np.empty((n, FOOT_COLUMNS))
        self._feet[:, FRICTION] = soles.friction
        self._forces = np.empty((0, 3))
        self.state = np.empty((n, 4))

    def read(self) -> np.ndarray:
        """(feet, 4): load, cone, margin and speed of each foot now; ``state``, overwritten by
        the next read."""
        model, data, feet = self.model, self.data, self._feet
        feet[:, ROTATION:POSITION] = data.xmat[self._bodies]
        feet[:, POSITION:CENTRE] = data.xpos[self._bodies]
        feet[:, CENTRE:TWIST] = data.xipos[self._bodies]
        for k, body in enumerate(self._bodies):
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, feet[k, TWIST:FRICTION], 0)
        if self._forces.shape[0] < data.ncon:
            self._forces = np.empty((2 * data.ncon, 3))
        forces = self._forces[:data.ncon]
        contact = data.contact
        contact_frame_forces(data.efc_force, contact.efc_address, contact.dim, forces)
        sole_states(forces, contact.frame, contact.pos, contact.geom, self.soles.foot_index, feet,
                    self.soles.edges, self.state)
        return self.state


@njit(cache=True)
def worst(into, now):
    """Kernel: two sole states combined worst-first into ``into``: smallest load and margin,
    largest cone and speed."""
    for k in range(into.shape[0]):
        into[k, LOAD] = min(into[k, LOAD], now[k, LOAD])
        into[k, CONE] = max(into[k, CONE], now[k, CONE])
        into[k, MARGIN] = min(into[k, MARGIN], now[k, MARGIN])
        into[k, SPEED] = max(into[k, SPEED], now[k, SPEED])


class HeldContactLog:
    """What a trial of a robot on held contacts records at each control step (``sim.trial_loop``):
    the floor's impulse on the robot (world frame, the sum of its physics steps' force times the
    timestep), the held contacts' frame positions at the step's start and the soles' states,
    worst over its physics steps (:func:`worst`)."""

    def __init__(self, scene, floor: np.ndarray, feet: np.ndarray, soles: np.ndarray):
        self.scene, self.floor, self.feet, self.soles = scene, floor, feet, soles
        self._sensor = SoleSensor(scene.model, scene.data, scene.soles)
        self._bodies = list(scene.foot_bodies)
        self._step = 0
        self._first = True

    @classmethod
    def of(cls, scene, steps: int) -> HeldContactLog:
        """An empty log of at most ``steps`` control steps of the scene's held contacts."""
        n = len(scene.foot_bodies)
        return cls(scene, np.zeros((steps, 3)), np.empty((steps, n, 3)), np.empty((steps, n, 4)))

    def add_state(self, k: int) -> None:
        """Start control step k: the held contacts' frame positions now."""
        self._step, self._first = k, True
        self.feet[k] = self.scene.data.xpos[self._bodies]

    def add_substep(self, floor_force: np.ndarray, timestep: float) -> None:
        """A physics step of the current control step: the floor's force on the robot, the soles."""
        k = self._step
        self.floor[k] += floor_force * timestep
        now = self._sensor.read()
        if self._first:
            self.soles[k] = now
        else:
            worst(self.soles[k], now)
        self._first = False

    def truncated(self, steps: int) -> HeldContactLog:
        """The log of the first ``steps`` control steps."""
        return HeldContactLog(self.scene, self.floor[:steps], self.feet[:steps], self.soles[:steps])


def slip_onset(states: np.ndarray) -> np.ndarray:
    """Per step of (steps, feet, 4) states and foot: the foot slides (module docstring)."""
    return (states[..., CONE] >= 1.0 - CONE_TOLERANCE) | (states[..., SPEED] > SLIP_SPEED)


def lift_onset(states: np.ndarray) -> np.ndarray:
    """Per step and foot: the centre of pressure is on an edge of the sole, or the foot is unloaded."""
    return states[..., MARGIN] <= LIFT_MARGIN
