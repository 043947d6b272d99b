"""The contact force on the robot of one MuJoCo physics step, summed over the contacts with the
environment: the wall's (and a standing robot's floor's, apart), in the world frame.

MuJoCo solves each contact c for its force in the contact frame, the first ``dim_c`` rows of the
constraint forces from ``efc_address_c`` (``mj_contactForce``): with elliptic cones (every scene
of this project: ``sim.scene.robot_spec``) these rows are the force itself, the normal one
first, then the two tangential ones (condim >= 3), then torsional and rolling torques (condim
4 and 6, left out here); a contact outside the solver (``efc_address`` < 0) carries none. The
rows of ``contact.frame`` are the contact frame's axes in the world frame, the normal first, and
a positive normal force pushes geom2 away from geom1, so the force on geom2 in the world frame is

    f_2 = R^T f_c,     R = frame (3 x 3, row-major),

and the force on the robot is f_2 when geom1 is the environment's, -f_2 otherwise.
:func:`contact_force_sums` does this for every contact in one compiled call; the tests compare it
with MuJoCo's own ``mj_contactForce``, contact by contact.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numba import njit


@njit(cache=True)
def contact_frame_force(efc_force, address, dim, c):
    """The force (normal, first tangential, second tangential) of contact c in its contact frame
    (module docstring): zero outside the solver, the tangential ones zero for condim 1."""
    first = address[c]
    if first < 0:
        return 0.0, 0.0, 0.0
    rows = min(dim[c], 3)
    normal = efc_force[first]
    t1 = efc_force[first + 1] if rows > 1 else 0.0
    t2 = efc_force[first + 2] if rows > 2 else 0.0
    return normal, t1, t2


@njit(cache=True)
def to_world(frame, c, normal, t1, t2):
    """The force (normal, t1, t2) of contact c in its contact frame, on its geom2 in the world
    frame: f_2 = R^T f_c (module docstring)."""
    return (frame[c, 0] * normal + frame[c, 3] * t1 + frame[c, 6] * t2,
            frame[c, 1] * normal + frame[c, 4] * t1 + frame[c, 7] * t2,
            frame[c, 2] * normal + frame[c, 5] * t1 + frame[c, 8] * t2)


@njit(cache=True)
def contact_force_sums(efc_force, address, dim, frame, geom, environment, wall, floor):
    """Kernel: adds the force on the robot of each contact (module docstring) to ``wall``, or, when
    ``floor`` is not empty, to ``floor`` for a contact that does not touch ``environment[0]`` (the wall);
    ``environment``: the environment's geom ids (a contact whose geom1 is one of them pushes
    the robot, its geom2, along +f_2)."""
    split = floor.shape[0] > 0
    for c in range(address.shape[0]):
        normal, t1, t2 = contact_frame_force(efc_force, address, dim, c)
        fx, fy, fz = to_world(frame, c, normal, t1, t2)
        geom1, geom2 = geom[c, 0], geom[c, 1]
        sign = -1.0
        for g in environment:
            if g == geom1:
                sign = 1.0
        target = floor if split and geom1 != environment[0] and geom2 != environment[0] else wall
        target[0] += sign * fx
        target[1] += sign * fy
        target[2] += sign * fz


@njit(cache=True)
def contact_frame_forces(efc_force, address, dim, forces):
    """Kernel: row c of ``forces`` (ncon x 3) the force of contact c in its contact frame
    (:func:`contact_frame_force`)."""
    for c in range(address.shape[0]):
        forces[c, 0], forces[c, 1], forces[c, 2] = contact_frame_force(efc_force, address, dim, c)


class ContactForces:
    """The environment's contact force on the robot in ``data`` of ``model``, after each physics
    step (module docstring); ``environment``: the geom ids, the wall's first, then a standing
    robot's floor."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, environment: tuple[int, ...]):
        if model.opt.cone != mujoco.mjtCone.mjCONE_ELLIPTIC:
            raise ValueError("the contact forces are read from an elliptic-cone model's constraint forces")
        self.data = data
        self.environment = np.array(environment, dtype=np.int64)
        self._no_floor = np.zeros(0)

    def prepare(self) -> None:
        """Load (or compile) the kernel now, on no contact (``ServoedPlant.prepare``)."""
        data, contact = self.data, self.data.contact
        rows = slice(0, 0)
        for floor in (self._no_floor, np.zeros(3)):
            contact_force_sums(data.efc_force[rows], contact.efc_address[rows], contact.dim[rows], contact.frame[rows],
                               contact.geom[rows], self.environment, np.zeros(3), floor)

    def add(self, wall: np.ndarray, floor: np.ndarray | None = None) -> None:
        """Adds the current step's force on the robot to ``wall``; given ``floor``, the contacts
        that do not touch the wall go to ``floor`` instead."""
        data = self.data
        if data.ncon == 0:
            return
        contact = data.contact
        contact_force_sums(data.efc_force, contact.efc_address, contact.dim, contact.frame, contact.geom,
                           self.environment, wall, self._no_floor if floor is None else floor)
