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

from impactqp.controller.model.held_contact_description import convex_hull
from impactqp.controller.model.humanoid_stance import edge_margins

LOAD, CONE, MARGIN, SPEED = range(4)
CONE_TOLERANCE = 1e-3
SLIP_SPEED = 0.01  # m/s
LIFT_MARGIN = 1e-3  # m


@dataclass(frozen=True)
class Soles:
    """The feet of a scene: body ids, their sphere geoms, sole polygons (foot axes) and each
    foot's mu, and which foot each sphere geom belongs to (``foot_of``, read at every physics
    step)."""

    bodies: tuple[int, ...]
    spheres: tuple[tuple[int, ...], ...]
    polygons: tuple[np.ndarray, ...]
    friction: tuple[float, ...]
    foot_of: dict

    @classmethod
    def of(cls, model: mujoco.MjModel, bodies, friction) -> Soles:
        """Every sphere geom of each foot body is a sole sphere; ``friction`` is one mu for every
        foot or one per foot."""
        spheres = tuple(
            tuple(g for g in range(model.ngeom) if model.geom_bodyid[g] == b and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE)
            for b in bodies
        )
        polygons = tuple(convex_hull(model.geom_pos[list(s), :2]) for s in spheres)
        foot_of = {g: k for k, foot in enumerate(spheres) for g in foot}
        mu = tuple(float(f) for f in np.broadcast_to(np.asarray(friction, dtype=float), (len(spheres),)))
        return cls(tuple(bodies), spheres, polygons, mu, foot_of)


def sole_state(model: mujoco.MjModel, data: mujoco.MjData, soles: Soles) -> np.ndarray:
    """(feet, 4): load, cone, margin and speed of each foot now (module docstring)."""
    n = len(soles.bodies)
    force, moment, speed = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros(n)
    wrench, twist = np.zeros(6), np.zeros((n, 6))
    for k, body in enumerate(soles.bodies):
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, twist[k], 0)
    for c in range(data.ncon):
        contact = data.contact[c]
        k = soles.foot_of.get(contact.geom1, soles.foot_of.get(contact.geom2))
        if k is None:
            continue
        mujoco.mj_contactForce(model, data, c, wrench)
        f = contact.frame.reshape(3, 3).T @ wrench[:3]
        force[k] += f if f[2] >= 0.0 else -f
        body = soles.bodies[k]
        local = data.xmat[body].reshape(3, 3).T @ (contact.pos - data.xpos[body])
        moment[k] += wrench[0] * local[:2]
        point = twist[k, 3:] + np.cross(twist[k, :3], contact.pos - data.xipos[body])
        speed[k] = max(speed[k], float(np.linalg.norm(point[:2])))
    state = np.zeros((n, 4))
    for k in range(n):
        load = force[k, 2]
        state[k] = load, 0.0, -np.inf, speed[k]
        if load > 0.0:
            state[k, CONE] = np.linalg.norm(force[k, :2]) / (soles.friction[k] * load)
            state[k, MARGIN] = edge_margins(soles.polygons[k], moment[k] / load).min()
    return state


def worst(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Two sole states combined worst-first: smallest load and margin, largest cone and speed."""
    out = np.maximum(a, b)
    out[:, [LOAD, MARGIN]] = np.minimum(a, b)[:, [LOAD, MARGIN]]
    return out


class HeldContactLog:
    """What a trial of a robot on held contacts records at each control step (``sim.trial_loop``):
    the floor's impulse on the robot (world frame, the sum of its physics steps' force times the
    timestep), the held contacts' frame positions at the step's start and the soles' states,
    worst over its physics steps (:func:`worst`)."""

    def __init__(self, scene, floor: np.ndarray, feet: np.ndarray, soles: np.ndarray):
        self.scene, self.floor, self.feet, self.soles = scene, floor, feet, soles
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
        self.feet[k] = self.scene.data.xpos[list(self.scene.foot_bodies)]

    def add_substep(self, floor_force: np.ndarray, timestep: float) -> None:
        """A physics step of the current control step: the floor's force on the robot, the soles."""
        scene, k = self.scene, self._step
        self.floor[k] += floor_force * timestep
        now = sole_state(scene.model, scene.data, scene.soles)
        self.soles[k] = now if self._first else worst(self.soles[k], now)
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
