"""The robust friction rows' impulses: the edges of the friction pyramid and their jump maps
(docs/frictional-impacts.md, "Robust rows"; the polyhedral form of Wang, Dehio, Tanguy,
Kheddar, IJRR 2023), for a fixed-base arm.

With Coulomb friction mu the impulse on the robot lies in the friction cone
{|iota_t| <= mu iota_n}. Its pyramid of k edges is d_i = n + mu_k t_i, t_i = cos(2 pi i / k) t1 +
sin(2 pi i / k) t2 the evenly spaced unit tangents of the contact frame (t1, t2, n)
(``frictional_impact.contact_frame``) and mu_k = mu / cos(pi / k): a polygon circumscribing
the cone's section, so that every impulse of the cone is a combination of the edges (with
mu_k = mu the polygon would be inscribed and miss the section between its edges). The impulse
along d_i that ends compression (n^T (v- + W iota) = 0), times 1 + c_r, is

    iota_i = G_i v-,   G_i = -(1 + c_r) d_i n^T / (n^T W d_i)

linear in v- as eq. (12) is (d_i = n gives eq. 12). The jump and the impulsive torque of edge i
are A_i = K G_i J and P_i = J^T G_i J, K and W the predictor's (J+ W for crb and gm, M^-1 J^T
with W = W_gm = J M^-1 J^T for classical): both rank one,

    A_i = s_i (K d_i)(J^T n)^T,   P_i = s_i (J^T d_i)(J^T n)^T,   s_i = -(1 + c_r) / (n^T W d_i).

Guard. n^T W d_i = n^T W n + mu n^T W t_i can be small or negative when the tangential
coupling of W is strong (mu |W_tn| near W_nn): sliding along such an edge barely slows the
normal approach, so the edge impulse that ends compression grows without bound and changes sign
at zero. Where n^T W d_i <= kappa n^T W n (kappa = :data:`EDGE_GUARD`) the rows use
kappa n^T W n: an edge impulse 1 / kappa times the frictionless one, the largest the rows
assume; the rows then ask more than that edge's own algebra, never less than its guarded
impulse in the same direction (conservative, and finite).

The **one-step preview** (mode ``slip``) keeps one edge, the one opposing the slip the next
cycle will have: d = n - mu s, s the unit tangential contact velocity of dq (the impulse
opposes slip), or d = n (frictionless) while the tangential speed is below :data:`SLIP_SPEED`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from . import validation
from .frictional_impact import contact_frame
from .jump import JumpModel, gm_inverse_inertia
from .model_terms import ModelTerms
from .validation import BadInputError

FRICTION_ROW_MODES = ("pyramid", "slip")
"""``pyramid``: every edge of the friction pyramid; ``slip``: the edge opposing the predicted slip."""
MAX_ROW_FRICTION = 2.0
"""Largest friction coefficient of the rows (the surfaces' own bound, ``postures.MAX_FRICTION``)."""
DEFAULT_EDGES, MIN_EDGES, MAX_EDGES = 4, 3, 16
"""Edges of the pyramid: 3 is the least polygon; 16 reach 98 % of the cone's radius (cos(pi/16))."""
EDGE_GUARD = 0.1
"""kappa: the rows' n^T W d_i is at least kappa n^T W n (module docstring, Guard)."""
SLIP_SPEED = 1e-3
"""m/s: below this tangential contact speed the preview mode's edge is the normal (no slip)."""


@dataclass(frozen=True)
class FrictionRows:
    """What the robust friction rows of an expected impact take: the Coulomb coefficient
    ``friction`` mu in [0, 2] (0: no friction rows, the frictionless rows alone), the number of
    pyramid ``edges`` k in [3, 16] and the ``mode``, "pyramid" (k edges) or "slip" (the one-step
    preview's one edge)."""

    friction: float = 0.0
    edges: int = DEFAULT_EDGES
    mode: str = "pyramid"

    def __post_init__(self):
        validation.number_in_range(self.friction, 0.0, MAX_ROW_FRICTION, "the friction of the impact rows", "")
        if isinstance(self.edges, bool) or not isinstance(self.edges, (int, np.integer)) or not (
            MIN_EDGES <= self.edges <= MAX_EDGES
        ):
            raise BadInputError(f"the pyramid edges must be an integer in [{MIN_EDGES}, {MAX_EDGES}], got {self.edges!r}")
        validation.name_in(self.mode, FRICTION_ROW_MODES, "the friction rows")

    @property
    def count(self) -> int:
        """The edges whose rows stack under the frictionless ones: 0 without friction, k for the
        pyramid, 1 for the slip preview."""
        if self.friction == 0.0:
            return 0
        return int(self.edges) if self.mode == "pyramid" else 1


class EdgeMatrices(NamedTuple):
    """The edges' joint-space maps of one state: jump A_i (edges x nv x nv) and impulsive torque
    P_i (edges x nv x nv), dq_jump = A_i dq- and J^T iota_i = P_i dq-."""

    jump: np.ndarray
    torque: np.ndarray


def pyramid_directions(normal: np.ndarray, friction: float, edges: int) -> np.ndarray:
    """d_i = n + mu_k t_i (edges x 3), mu_k = mu / cos(pi / k), t_i = cos(2 pi i / k) t1 +
    sin(2 pi i / k) t2: the pyramid circumscribing the cone of ``friction`` (module docstring)."""
    frame = contact_frame(np.asarray(normal, dtype=float))
    angles = 2.0 * math.pi * np.arange(edges) / edges
    tangents = np.cos(angles)[:, None] * frame[:, 0] + np.sin(angles)[:, None] * frame[:, 1]
    return frame[:, 2] + friction / math.cos(math.pi / edges) * tangents


def edge_directions(rows: FrictionRows, normal: np.ndarray, tangential_velocity: np.ndarray) -> np.ndarray:
    """The edge directions of ``rows`` (rows.count x 3): the pyramid's, or the preview's one edge
    opposing the tangential contact velocity ``tangential_velocity``; none without friction."""
    if rows.count == 0:
        return np.empty((0, 3))
    if rows.mode == "pyramid":
        return pyramid_directions(normal, rows.friction, rows.edges)
    direction = np.empty((1, 3))
    slip_direction_into(np.eye(3), np.asarray(tangential_velocity, dtype=float), normal, rows.friction, direction[0])
    return direction


def response_maps(model: JumpModel, terms: ModelTerms, normal: np.ndarray, restitution: float):
    """(K, W) of the predictor ``model`` at a fixed-base state: its impulse-to-jump map and the
    inverse inertia its impulse acts through (W_gm for the classical law). The normal-only
    classical law and robots on held contacts have no friction rows (bad input)."""
    if model.name == "classical_normal":
        raise BadInputError("the classical_normal model keeps the normal impulse only: it has no friction rows")
    if terms.held_jacobian.shape[0]:
        raise BadInputError("friction rows are for fixed-base arms; a robot on held contacts has none")
    maps = model.unit_maps(terms, normal, restitution)
    return maps.K, (gm_inverse_inertia(terms) if maps.W is None else maps.W)


def edge_matrices(model: JumpModel, terms: ModelTerms, normal: np.ndarray, directions: np.ndarray, restitution: float):
    """A_i and P_i of every edge direction (rows of ``directions``) at this state, for the
    predictor ``model`` (``EdgeMatrices``; compiled, ``edge_matrices_into``)."""
    n = terms.J.shape[1]
    out = EdgeMatrices(np.empty((len(directions), n, n)), np.empty((len(directions), n, n)))
    K, W = response_maps(model, terms, normal, restitution)
    edge_matrices_into(terms.J, K, W, normal, directions, restitution, out.jump, out.torque)
    return out


@njit(cache=True)
def edge_matrices_into(J, K, W, normal, directions, restitution, jump, torque):
    """Kernel: A_i = s_i (K d_i)(J^T n)^T and P_i = s_i (J^T d_i)(J^T n)^T with
    s_i = -(1 + c_r) / max(n^T W d_i, kappa n^T W n), written into ``jump`` and ``torque``."""
    nv = J.shape[1]
    Jt_normal = np.zeros(nv)
    Wt_normal = np.zeros(3)
    for a in range(3):
        for j in range(nv):
            Jt_normal[j] += J[a, j] * normal[a]
        for b in range(3):
            Wt_normal[b] += W[a, b] * normal[a]
    floor = EDGE_GUARD * (Wt_normal[0] * normal[0] + Wt_normal[1] * normal[1] + Wt_normal[2] * normal[2])
    Kd = np.empty(nv)
    Jtd = np.empty(nv)
    for e in range(directions.shape[0]):
        d = directions[e]
        s = -(1.0 + restitution) / max(Wt_normal[0] * d[0] + Wt_normal[1] * d[1] + Wt_normal[2] * d[2], floor)
        for i in range(nv):
            Kd[i] = s * (K[i, 0] * d[0] + K[i, 1] * d[1] + K[i, 2] * d[2])
            Jtd[i] = s * (J[0, i] * d[0] + J[1, i] * d[1] + J[2, i] * d[2])
        for i in range(nv):
            for j in range(nv):
                jump[e, i, j] = Kd[i] * Jt_normal[j]
                torque[e, i, j] = Jtd[i] * Jt_normal[j]


@njit(cache=True)
def slip_direction_into(J, dq, normal, friction, direction):
    """Kernel: the preview's edge d = n - mu s, s = v_t / |v_t| with v = J dq and
    v_t = v - (n.v) n, or d = n while |v_t| < ``SLIP_SPEED``; written into ``direction`` (3)."""
    v = np.zeros(3)
    for a in range(3):
        for j in range(J.shape[1]):
            v[a] += J[a, j] * dq[j]
    normal_speed = v[0] * normal[0] + v[1] * normal[1] + v[2] * normal[2]
    for a in range(3):
        v[a] -= normal_speed * normal[a]
    speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    for a in range(3):
        direction[a] = normal[a] - (friction * v[a] / speed if speed >= SLIP_SPEED else 0.0)
