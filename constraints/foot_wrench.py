"""Impact-aware foot rows: at the peak of the impact force, each held contact's wrench stays inside
its sole's friction cone and its centre of pressure inside the sole (docs/whole-body-qp.md)."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.capture import GRAVITY
from impactqp.controller.model.held_contact_description import convex_hull
from impactqp.controller.model.jump_kernels import product
from impactqp.controller.model.max_speed import sole_rows
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError

from .constraint import Constraint, ControlCycle
from .impact_model import ExpectedImpact
from .vertex_blocks import VertexBlocks


def standing_map(foot_positions: np.ndarray) -> np.ndarray:
    """S (6k x 6): the least-norm foot wrenches w (6 per foot, world axes, about each foot frame)
    whose sum balances a wrench b about the world origin, w = S b with S = A^+ and
    A = [[I, 0, I, 0, ...], [[p_1]x, I, [p_2]x, I, ...]] (the wrenches moved to the origin)."""
    A = np.zeros((6, 6 * len(foot_positions)))
    for k, p in enumerate(foot_positions):
        A[:3, 6 * k:6 * k + 3] = np.eye(3)
        A[3:, 6 * k:6 * k + 3] = [[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]]
        A[3:, 6 * k + 3:6 * k + 6] = np.eye(3)
    return np.linalg.pinv(A)


class FootWrenchLimit(Constraint):
    """Each held contact's wrench at the peak of the impact force inside its friction cone and its
    sole, the closed form's ``foot_slip`` and ``foot_lift`` (``controller.model.max_speed``) as
    rows linear in dv.

    With the velocity v' = v + dv h, the expected impact's impulse is iota = G J v' (G of the
    chosen predictor: crb (12), (20), gm (12), (22), classical (6)) and the held contacts' impulsive
    wrenches, the feet held (docs/floating-base.md),

        lambda = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T iota = L v',    L = -Z G J,

    linear in dv. The hand's force peaks at iota / T, T the contact's equivalent duration (its
    impulse over its peak force); at that peak the ground's wrench on foot k is F_k / T with
    F_k = T w_k + lambda_k, w_k the standing wrench: the least-norm foot wrenches that carry the
    robot's weight m g at its CoM c (:func:`standing_map`). Per foot, in its axes (the rotation R_k
    of its frame, fixed at construction: the feet do not move), the rows e . F_k <= 0 are

    - ``slip``: u . F_xy - mu F_z <= 0 with u the direction of F_xy at dv = 0: the friction cone's
      supporting plane at this cycle's predicted wrench (it holds whenever the cone does, and is
      the cone itself at dv = 0, so it binds at the closed form's speed; re-taken every cycle);
    - ``lift``: for each edge e of the convex sole (outward normal nu_e, corner a_e, the held
      contact's ``depth`` below the frame), nu_e . (-tau_y, tau_x) - (nu_e . a_e) f_z <= 0 about
      the sole (``max_speed.sole_rows``): the centre of pressure inside the sole (and f_z >= 0).

    Divided by the mass m (velocity units) and written at the jerk horizon h like the other impact
    rows: C dv <= (-T e . w_k / m - C v) / h, C = e . L_k / m. Unbounded while no impact is coming;
    relaxed to the largest correction the cycle allows when the state already violates them.

    Simplifications (those of the closed form): the feet's impulsive wrenches peak with the hand's
    force, in the feet-held model's proportions; the standing wrench is gravity's alone.
    """

    relaxed = True

    def __init__(self, impact: ExpectedImpact, robot: RobotModel, q_start: np.ndarray, duration: float):
        if not impact.held_contacts or not robot.description.held_contacts:
            raise BadInputError("the foot rows need an impact with held contacts (the robot's feet)")
        if not duration > 0.0:
            raise BadInputError(f"the contact's equivalent duration must be > 0 s, got {duration}")
        self.impact = impact
        self.duration = float(duration)
        contacts = robot.description.held_contacts
        placements = robot.frame_placements(q_start)
        soles = [convex_hull(c.sole) for c in contacts]
        edges = max(len(s) for s in soles)
        self._rotations = np.array([placements[c.frame].rotation for c in contacts])
        self._standing = standing_map([placements[c.frame].translation for c in contacts])
        # each foot's sole rows on its local wrench (padded with zero rows to the largest sole)
        self._soles = np.zeros((len(contacts), edges, 6))
        for k, (contact, sole) in enumerate(zip(contacts, soles)):
            self._soles[k, :len(sole)] = np.array([sole_rows(sole, contact.depth, e) for e in np.eye(6)]).T
        self._friction = np.array([c.friction for c in contacts])
        self.labels = tuple(
            label for c, sole in zip(contacts, soles)
            for label in (f"slip {c.label}", *(f"lift {c.label} edge {e}" for e in range(edges)))
        )
        self.rows = len(self.labels)
        self.name = f"foot_wrench[{impact.name}]"

    def kernel_parameters(self) -> np.ndarray:
        """The number of feet k, the duration T, mu_k, the feet's rotations R_k, the standing map S
        (6k x 6) and the soles' rows (k x edges x 6), each row by row."""
        feet = len(self._friction)
        return np.concatenate([
            [feet, self.duration], self._friction, self._rotations.ravel(), self._standing.ravel(), self._soles.ravel(),
        ])

    def compute_into(self, terms, cycle: ControlCycle, C, lower, upper) -> None:
        lower[:] = -np.inf
        if not self.impact.is_active(terms):
            C[:] = 0.0
            upper[:] = np.inf
            return
        impact, J = self.impact, np.ascontiguousarray(terms.J6[:3])
        foot_wrench_rows(
            (impact.held_impulse_map(terms), J, impact.row_matrices(terms).impulse_map),
            (terms.dq, terms.com, terms.mass),
            (self._rotations, self._standing, self._soles, self._friction),
            (self.duration, 1.0 / cycle.horizon), C, upper,
        )


@njit(cache=True)
def foot_wrench_rows(maps, state, feet, scale, C, upper):
    """Kernel: the rows of :class:`FootWrenchLimit` (its docstring), for maps = (Z, J, G) with
    Z = (Jf M^-1 Jf^T)^-1 Jf M^-1 J^T (``ExpectedImpact.held_impulse_map``, computed with the
    jump maps), state = (v, c, m), feet = (R_k, the standing map S, the soles' rows on the local
    wrench, mu_k) and scale = (T, 1 / h); per foot the slip row, then its sole's rows."""
    Z, J, G = maps
    dq, com, mass = state
    rotations, standing, soles, friction = feet
    duration, inv_h = scale
    L = -product(product(Z, G), J)
    weight = mass * GRAVITY
    gravity_wrench = np.array([0.0, 0.0, weight, com[1] * weight, -com[0] * weight, 0.0])
    w = duration * product(standing, gravity_wrench.reshape((6, 1)))[:, 0]  # T w
    peak = w + product(L, dq.reshape((-1, 1)))[:, 0]  # F at dv = 0
    per_foot = 1 + soles.shape[1]
    local = np.empty(6)
    world = np.empty(6)
    for k in range(rotations.shape[0]):
        R = rotations[k]
        fx, fy = 0.0, 0.0  # the foot's tangential force at dv = 0, in its axes
        for i in range(3):
            fx += R[i, 0] * peak[6 * k + i]
            fy += R[i, 1] * peak[6 * k + i]
        norm = np.sqrt(fx * fx + fy * fy)
        for r in range(per_foot):
            if r == 0:
                local[:] = 0.0
                local[0], local[1], local[2] = 1.0, 0.0, -friction[k]
                if norm > 0.0:
                    local[0], local[1] = fx / norm, fy / norm
            else:
                local[:] = soles[k, r - 1]
            for i in range(3):
                world[i] = R[i, 0] * local[0] + R[i, 1] * local[1] + R[i, 2] * local[2]
                world[3 + i] = R[i, 0] * local[3] + R[i, 1] * local[4] + R[i, 2] * local[5]
            row = k * per_foot + r
            offset = 0.0  # e . F_k at dv = 0 (T w_k + L_k v): upper = -e . F_k / (m h)
            for i in range(6):
                offset += world[i] * peak[6 * k + i]
            for j in range(C.shape[1]):
                total = 0.0
                for i in range(6):
                    total += world[i] * L[6 * k + i, j]
                C[row, j] = total / mass
            upper[row] = -offset / mass * inv_h


class EdgeFootWrenchLimit(VertexBlocks, FootWrenchLimit):
    """The feet's rows of :class:`FootWrenchLimit` for the frictionless impulse, then the same
    rows for each edge impulse of the impact's friction rows (``ExpectedImpact`` with
    ``FrictionRows``, docs/frictional-impacts.md): with iota_i = G_i J v' the held contacts'
    impulsive wrenches lambda_i = -Z G_i J v' and every foot's wrench at the peak of each
    vertex's force inside its cone and its sole (each vertex's own slip row: the cone's
    supporting plane at that vertex's predicted wrench). (1 + edges) x the frictionless rows;
    without friction, the rows of :class:`FootWrenchLimit` alone."""

    def __init__(self, impact: ExpectedImpact, robot: RobotModel, q_start: np.ndarray, duration: float):
        super().__init__(impact, robot, q_start, duration)
        self.stack_vertices()
        edges = impact.friction.count
        self.labels = self.labels + tuple(f"edge {e}: {label}" for e in range(edges) for label in self.labels)
        self.name = f"foot_wrench_edges[{impact.name}]"

    def vertex_rows_into(self, terms, cycle: ControlCycle, impulse_map, C, upper) -> None:
        foot_wrench_rows(
            (self.impact.held_impulse_map(terms), np.ascontiguousarray(terms.J6[:3]), impulse_map),
            (terms.dq, terms.com, terms.mass),
            (self._rotations, self._standing, self._soles, self._friction),
            (self.duration, 1.0 / cycle.horizon), C, upper,
        )
