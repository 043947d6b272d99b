"""The robust friction rows' impulses: the edges of the friction pyramid and their jump maps
(docs/frictional-impacts.md, "Robust rows"; the polyhedral form of Wang, Dehio, Tanguy,
Kheddar, IJRR 2023), for a fixed-base arm and for a robot standing on held contacts.

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

**Held contacts** (a humanoid's soles, :func:`held_edge_maps_into`): the same edge impulses
with the predictor's held-contact W and K (W_gm = J P_f J^T and K = P_f J^T for the classical
law, J# W for gm and crb, ``jump``'s docstring); their maps A_i = K G_i J and P_i = J^T G_i J
and the edge impulse maps G_i themselves, which the capture region's and the feet's rows of
each edge take (``constraints.capture_constraint``, ``constraints.foot_wrench``).

The **one-step preview** (mode ``slip``) keeps three edges, those of the cone's sector within
+-alpha (alpha = :data:`SLIP_SECTOR`) of the direction opposing the slip the next cycle will
have, when that slip is certain to last through the impact; the whole cone (the 3-edge pyramid)
when it is not. With v = J dq the contact velocity, u_n = n^T v, v_t its tangential part and
s = v_t / |v_t|: during a slip du/dp = W (n - mu s(p)), so the normal approach slows at least at
the rate c = n^T W n - mu |P W^T n| (P = I - n n^T) and the impact's normal impulse is at most
p_max = (1 + sqrt(2) c_r) |u_n| / c (compression ends by |u_n| / c; the restitution phase, of
either law with e = c_r, by sqrt(2) c_r |u_n| / c more), while the tangential velocity moves by
at most D = (|P W n| + mu ||P W P||_F) p_max. **Certain** when |v_t| >= :data:`SLIP_SPEED`,
c > 0 and D <= |v_t| sin(alpha): v_t then stays within an angle alpha of its start and never
stops, so the impulse lies in the sector. Its edges are d_j = n - mu_a (cos(theta_j) s +
sin(theta_j) (n x s)), theta_j in {-alpha, 0, alpha}, mu_a = mu / cos(alpha / 2): two segments
circumscribing the sector's arc, as the pyramid circumscribes the cone. Otherwise the edges are
the 3-edge pyramid's (mu_3 = 2 mu), which covers every impulse of the cone.
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
from .jump_kernels import welded_inverse_inertia
from .model_terms import ModelTerms
from .validation import BadInputError

FRICTION_ROW_MODES = ("pyramid", "slip")
"""``pyramid``: every edge of the friction pyramid; ``slip``: the sector opposing a certain slip (module docstring)."""
MAX_ROW_FRICTION = 2.0
"""Largest friction coefficient of the rows (the surfaces' own bound, ``postures.MAX_FRICTION``)."""
DEFAULT_EDGES, MIN_EDGES, MAX_EDGES = 4, 3, 16
"""Edges of the pyramid: 3 is the least polygon; 16 reach 98 % of the cone's radius (cos(pi/16))."""
EDGE_GUARD = 0.1
"""kappa: the rows' n^T W d_i is at least kappa n^T W n (module docstring, Guard)."""
SLIP_SPEED = 1e-3
"""m/s: below this tangential contact speed the preview's slip direction is uncertain (the whole cone)."""
SLIP_SECTOR = math.pi / 6
"""alpha: the half-angle of the preview's sector around the direction opposing the slip."""
SLIP_EDGES = 3
"""The preview's edges: the sector's three, or the 3-edge pyramid's when the slip is uncertain."""


@dataclass(frozen=True)
class FrictionRows:
    """What the robust friction rows of an expected impact take: the Coulomb coefficient
    ``friction`` mu in [0, 2] (0: no friction rows, the frictionless rows alone), the number of
    pyramid ``edges`` k in [3, 16] and the ``mode``, "pyramid" (k edges) or "slip" (the one-step
    preview's three: its sector or the 3-edge pyramid)."""

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
        pyramid, 3 for the slip preview."""
        if self.friction == 0.0:
            return 0
        return int(self.edges) if self.mode == "pyramid" else SLIP_EDGES


class Edges(NamedTuple):
    """The edges of one impact: their ``directions`` d_i (edges x 3), the unit ``normal`` n and
    the restitution c_r."""

    directions: np.ndarray
    normal: np.ndarray
    restitution: float


NO_MATRIX = np.empty((0, 0))
"""M^-1's place in ``edge_matrices_into`` for crb and gm, which do not read it (nor compute it)."""


class EdgeMatrices(NamedTuple):
    """The edges' joint-space maps of one state: jump A_i (edges x nv x nv) and impulsive torque
    P_i (edges x nv x nv), dq_jump = A_i dq- and J^T iota_i = P_i dq-."""

    jump: np.ndarray
    torque: np.ndarray

    @classmethod
    def of(cls, buffer: np.ndarray) -> EdgeMatrices:
        """The maps held in one buffer (2 x edges x nv x nv: the jumps, then the torques)."""
        return cls(buffer[0], buffer[1])


def pyramid_directions(normal: np.ndarray, friction: float, edges: int) -> np.ndarray:
    """d_i = n + mu_k t_i (edges x 3), mu_k = mu / cos(pi / k), t_i = cos(2 pi i / k) t1 +
    sin(2 pi i / k) t2: the pyramid circumscribing the cone of ``friction`` (module docstring)."""
    frame = contact_frame(np.asarray(normal, dtype=float))
    angles = 2.0 * math.pi * np.arange(edges) / edges
    tangents = np.cos(angles)[:, None] * frame[:, 0] + np.sin(angles)[:, None] * frame[:, 1]
    return frame[:, 2] + friction / math.cos(math.pi / edges) * tangents


def edge_directions(rows: FrictionRows, normal: np.ndarray, velocity: np.ndarray, W: np.ndarray, restitution: float):
    """The edge directions of ``rows`` (rows.count x 3): the pyramid's, or the preview's three
    (its sector or the 3-edge pyramid, module docstring) at the contact velocity ``velocity``
    with the inverse inertia ``W`` and the restitution c_r; none without friction."""
    if rows.count == 0:
        return np.empty((0, 3))
    if rows.mode == "pyramid":
        return pyramid_directions(normal, rows.friction, rows.edges)
    normal = np.asarray(normal, dtype=float)
    directions = pyramid_directions(normal, rows.friction, SLIP_EDGES)
    slip_edges_into(np.asarray(velocity, dtype=float), np.asarray(W, dtype=float), normal, rows.friction, restitution,
                    directions)
    return directions


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


def held_response_maps(model: JumpModel, terms: ModelTerms, normal: np.ndarray, restitution: float):
    """(K, W) of the predictor ``model`` at a state on held contacts: its held-contact
    impulse-to-jump map and inverse inertia (W_gm = J P_f J^T for the classical law)."""
    maps = model.unit_maps(terms, normal, restitution)
    return maps.K, (gm_inverse_inertia(terms) if maps.W is None else maps.W)


def edge_impulse_maps(W: np.ndarray, edges: Edges) -> np.ndarray:
    """G_i = -(1 + c_r) d_i n^T / max(n^T W d_i, kappa n^T W n) (edges x 3 x 3): the edge
    impulses iota_i = G_i v- (module docstring, with its guard)."""
    normal, directions = edges.normal, edges.directions
    Wt_normal = W.T @ normal
    denominators = np.maximum(directions @ Wt_normal, EDGE_GUARD * (normal @ Wt_normal))
    return -(1.0 + edges.restitution) * directions[:, :, None] * normal[None, None, :] / denominators[:, None, None]


def held_edge_maps_into(response: tuple, J: np.ndarray, edges: Edges, out: np.ndarray, impulses: np.ndarray) -> None:
    """On held contacts: A_i = K G_i J and P_i = J^T G_i J of the ``edges`` into ``out``
    (2 x edges x nv x nv, ``EdgeMatrices.of(out)``) and G_i into ``impulses`` (edges x 3 x 3),
    for the predictor's held-contact maps ``response`` = (K, W) (:func:`held_response_maps`) and
    the contact Jacobian J."""
    K, W = response
    impulses[:] = edge_impulse_maps(W, edges)
    GJ = impulses @ J
    np.matmul(K, GJ, out=out[0])
    np.matmul(J.T, GJ, out=out[1])


def edge_inverse_inertia(model: JumpModel, terms: ModelTerms) -> np.ndarray:
    """W the predictor's edge impulses act through, at a fixed-base state: W_crb (20) for crb
    (compiled, ``welded_inverse_inertia``), W_gm = J M^-1 J^T (22) for gm and classical; the
    per-cycle form of ``response_maps``' W, its checks done once by the caller."""
    if model.name == "crb":
        return welded_inverse_inertia(terms.contact_point, terms.com, terms.inertia_com, terms.mass)
    return gm_inverse_inertia(terms)


def fill_edge_matrices(model: JumpModel, terms: ModelTerms, W: np.ndarray, edges: Edges, out: np.ndarray) -> None:
    """A_i and P_i of the ``edges`` (directions, normal, restitution) at this state into ``out``
    (2 x edges x nv x nv: ``EdgeMatrices.of(out)``), for the predictor ``model`` whose inverse
    inertia is ``W`` (compiled, ``edge_matrices_into``; K d_i = M^-1 J^T d_i for classical,
    J^T (J J^T)^-1 W d_i for crb and gm)."""
    M_inv = terms.M_inv if model.name == "classical" else NO_MATRIX
    edge_matrices_into(terms.J, terms.JJt_inv, M_inv, W, edges.directions, edges.normal, edges.restitution, out)


def edge_matrices(model: JumpModel, terms: ModelTerms, normal: np.ndarray, directions: np.ndarray, restitution: float):
    """A_i and P_i of every edge direction (rows of ``directions``) at this state, for the
    predictor ``model`` (``EdgeMatrices``; the checks of ``response_maps``, then
    :func:`fill_edge_matrices`)."""
    n = terms.J.shape[1]
    out = np.empty((2, len(directions), n, n))
    W = response_maps(model, terms, normal, restitution)[1]
    fill_edge_matrices(model, terms, W, Edges(np.asarray(directions, dtype=float), np.asarray(normal, dtype=float), restitution), out)
    return EdgeMatrices.of(out)


@njit(cache=True)
def edge_matrices_into(J, JJt_inv, M_inv, W, directions, normal, restitution, out):
    """Kernel: A_i = s_i (K d_i)(J^T n)^T into out[0, i] and P_i = s_i (J^T d_i)(J^T n)^T into
    out[1, i], s_i = -(1 + c_r) / max(n^T W d_i, kappa n^T W n), K d_i = M^-1 J^T d_i when
    ``M_inv`` is given (classical; empty otherwise) or J^T (J J^T)^-1 W d_i."""
    classical = M_inv.shape[0] > 0
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
    Wd = np.empty(3)
    y = np.empty(3)
    for e in range(directions.shape[0]):
        d = directions[e]
        s = -(1.0 + restitution) / max(Wt_normal[0] * d[0] + Wt_normal[1] * d[1] + Wt_normal[2] * d[2], floor)
        for i in range(nv):
            Jtd[i] = J[0, i] * d[0] + J[1, i] * d[1] + J[2, i] * d[2]
        if classical:
            for i in range(nv):
                total = 0.0
                for j in range(nv):
                    total += M_inv[i, j] * Jtd[j]
                Kd[i] = s * total
        else:
            for a in range(3):
                Wd[a] = W[a, 0] * d[0] + W[a, 1] * d[1] + W[a, 2] * d[2]
            for a in range(3):
                y[a] = JJt_inv[a, 0] * Wd[0] + JJt_inv[a, 1] * Wd[1] + JJt_inv[a, 2] * Wd[2]
            for i in range(nv):
                Kd[i] = s * (J[0, i] * y[0] + J[1, i] * y[1] + J[2, i] * y[2])
        for i in range(nv):
            Jtd[i] *= s
        for i in range(nv):
            for j in range(nv):
                out[0, e, i, j] = Kd[i] * Jt_normal[j]
                out[1, e, i, j] = Jtd[i] * Jt_normal[j]


@njit(cache=True)
def slip_edges_into(velocity, W, normal, friction, restitution, directions):
    """Kernel: the preview's edges at the contact velocity ``velocity`` (3) into ``directions``
    (3 x 3), which holds the 3-edge pyramid on entry: left so when the slip is uncertain, else
    overwritten by the sector's d_j = n - mu_a (cos(theta_j) s + sin(theta_j) (n x s)) (module
    docstring)."""
    normal_speed = velocity[0] * normal[0] + velocity[1] * normal[1] + velocity[2] * normal[2]
    v_t = np.empty(3)
    for a in range(3):
        v_t[a] = velocity[a] - normal_speed * normal[a]
    speed = math.sqrt(v_t[0] * v_t[0] + v_t[1] * v_t[1] + v_t[2] * v_t[2])
    if speed < SLIP_SPEED:
        return
    Wn = np.zeros(3)  # W n
    Wtn = np.zeros(3)  # W^T n
    for a in range(3):
        for b in range(3):
            Wn[a] += W[a, b] * normal[b]
            Wtn[a] += W[b, a] * normal[b]
    W_nn = Wn[0] * normal[0] + Wn[1] * normal[1] + Wn[2] * normal[2]
    coupling_in = 0.0  # |P W^T n|
    coupling_out = 0.0  # |P W n|
    for a in range(3):
        coupling_in += (Wtn[a] - W_nn * normal[a]) ** 2
        coupling_out += (Wn[a] - W_nn * normal[a]) ** 2
    rate = W_nn - friction * math.sqrt(coupling_in)
    if rate <= 0.0:
        return
    projected = 0.0  # ||P W P||_F^2
    for a in range(3):
        for b in range(3):
            entry = W[a, b]
            for c in range(3):
                entry -= normal[a] * normal[c] * W[c, b] + W[a, c] * normal[c] * normal[b]
            entry += normal[a] * W_nn * normal[b]
            projected += entry * entry
    impulse = (1.0 + math.sqrt(2.0) * restitution) * max(-normal_speed, 0.0) / rate
    drift = (math.sqrt(coupling_out) + friction * math.sqrt(projected)) * impulse
    if drift > speed * math.sin(SLIP_SECTOR):
        return
    radius = friction / math.cos(0.5 * SLIP_SECTOR)
    s = v_t / speed
    w = np.array([normal[1] * s[2] - normal[2] * s[1], normal[2] * s[0] - normal[0] * s[2], normal[0] * s[1] - normal[1] * s[0]])
    for j in range(3):
        angle = (j - 1) * SLIP_SECTOR
        for a in range(3):
            directions[j, a] = normal[a] - radius * (math.cos(angle) * s[a] + math.sin(angle) * w[a])
