"""The model terms of one state of a robot (``RobotModel.terms``), and the compiled kernels
that fill and check them.

Every frame quantity is world-aligned (Pinocchio's LOCAL_WORLD_ALIGNED): for a frame with twist
[v_p; w] = J6 dq, its time derivative is J6 ddq + dJ6 dq, where dJ6 dq is the frame's classical
acceleration at ddq = 0. The same holds for the centre of mass: dc = Jcom dq and
ddc = Jcom ddq + dJcom dq. For a floating base, q holds the free flyer's coordinates (position,
quaternion) before the joints' and dq = v the base twist (base frame) before the joint rates,
Pinocchio's free-flyer convention.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from .validation import BadInputError

_FILLS = itertools.count(1)
LAZY_FIELDS = ("M", "h", "dJ6_dq", "JJt_inv")
"""The fields of ModelTerms that a fill may leave to their first read (``fill_lazy``)."""


class FrameState(NamedTuple):
    """A frame's world position, rotation, world-aligned Jacobian (6 x nv) and drift dJ6 dq."""

    position: np.ndarray
    rotation: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray


class BodyTerms(NamedTuple):
    """The terms of a state beyond the contact's that a whole-body QP reads: M^-1
    (Pinocchio's ``computeMinverse``), the centre of mass's Jacobian ``Jcom`` (3 x nv) and drift
    dJcom dq, and the named frames of the description (``frames``: name -> FrameState)."""

    M_inv: np.ndarray
    Jcom: np.ndarray
    dJcom_dq: np.ndarray
    frames: dict[str, FrameState]


@dataclass(eq=False)
class ModelTerms:
    """Every model quantity of one state (q, dq), computed once (``RobotModel.terms``).

    Attributes are world-aligned: ``J`` is the 3 x nv linear Jacobian of the contact point p,
    ``J6`` the 6 x nv (linear; angular) Jacobian of the contact frame, ``dJ6_dq`` its drift,
    ``M`` the joint-space inertia matrix, ``h`` the bias forces (Coriolis, centrifugal, gravity),
    ``com`` the centre of mass of the moving links, ``mass`` their total mass and
    ``inertia_com`` the rotational inertia of the locked robot about ``com`` (world axes), used
    by the composite-rigid-body model (20). ``JJt_inv`` is (J J^T)^-1, so that the right
    inverse of (17) is J+ = J^T (J J^T)^-1.

    ``held_jacobian`` Jf (6 rows per held contact, in the description's order, linear then
    angular rows) and ``held_drift`` dJf dq are the held contacts' (a humanoid's soles): a
    fixed-base arm holds none (0 x nv and 0), the case of the held-contact jump maps with Jf
    empty (``controller.model.jump``).

    ``body`` holds M^-1, Jcom, dJcom dq and the named frames (:class:`BodyTerms`): a floating
    base fills it with everything else in one pass; a fixed base leaves it None and
    ``compute_body`` (the model's ``body_terms``) computes it on first use, once per fill.

    Lazily filled fields: a fill may leave any of ``LAZY_FIELDS`` (M, h, dJ6_dq, JJt_inv)
    unset (None at construction, or ``refilled(pending=...)``); the first read of one calls
    ``fill_lazy(terms, name)``, the model's, which returns that field and the others computed in
    the same pass, kept until the next fill. An arm's ``RobotModel.terms`` (a prediction from q)
    leaves M, h and dJ6_dq to a first read, a floating base's refill M, h and JJt_inv, which its
    whole-body QP does not read; a controller's ``update_terms`` of an arm fills every field
    of its buffer (``RobotModel.empty_terms``) at once.

    ``cycle_data`` is the Pinocchio data of an arm's per-cycle buffer (None elsewhere): its
    ``computeAllTerms`` writes M, h, com and contact_point, which are views of it (no copy), and
    its Cholesky factor of M gives M^-1 (``compute_inverse_inertia``); ``cycle_arrays`` =
    ((``data.J``, ``data.dJ``, p, R), ``data.Ig``, incoming, state, contact) are that data's
    world-frame joint Jacobians, their time variation, the contact frame's placement (views of
    the data) and its centroidal inertia, which J6, dJ6 dq, (J J^T)^-1 and the inertia about the
    centre of mass are computed from (``arm_cycle_terms``), the [q; dq] buffer a caller's
    read-only or strided state is copied into (the kernels read writable row-major arrays: one
    compiled signature each), the flat array that J6, dJ6 dq, (J J^T)^-1, dq, the contact
    rotation and q are views of (``arm_state``, ``arm_state_views``), its first part,
    ``contact_terms``, and the locked robot's [com, inertia_com, mass] (``locked_body``, the
    inertia about the centre of mass a view of it).

    ``frame_arrays`` = (J6, dJ6 dq, p, R) stacked over a floating base's frames (its contact
    frame, its held contacts, its named frames, in this order: F x 6 x nv, F x 6, F x 3,
    F x 3 x 3) are the arrays its fill writes (``floating_kernels.floating_frames_into``), of
    which the buffer's contact, held-contact and frame fields are views (None elsewhere).

    A controller refills one ModelTerms per cycle (``RobotModel.update_terms``); ``stamp``
    changes at every fill (and for a ``dataclasses.replace`` copy), so anything cached per
    state keys on it. The derived quantities below are computed on first use, once per fill.
    """

    q: np.ndarray
    dq: np.ndarray
    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray  # dJ6/dt dq: contact-frame acceleration at ddq = 0
    JJt_inv: np.ndarray
    contact_point: np.ndarray
    contact_rotation: np.ndarray
    com: np.ndarray
    mass: float
    inertia_com: np.ndarray
    held_jacobian: np.ndarray | None = field(default=None, repr=False)
    held_drift: np.ndarray | None = field(default=None, repr=False)
    body: BodyTerms | None = field(default=None, repr=False)
    compute_body: Callable[[np.ndarray, np.ndarray], BodyTerms] | None = field(default=None, repr=False)
    compute_inverse_inertia: Callable[[np.ndarray], np.ndarray] | None = field(default=None, repr=False)
    fill_lazy: Callable[[ModelTerms, str], dict[str, np.ndarray]] | None = field(default=None, repr=False)
    cycle_data: object = field(default=None, repr=False)
    cycle_arrays: tuple | None = field(default=None, repr=False)
    frame_arrays: tuple | None = field(default=None, repr=False)
    stamp: int = field(init=False, repr=False)
    _derived: dict = field(init=False, repr=False)

    def __post_init__(self):
        self.stamp = next(_FILLS)
        if self.held_jacobian is None:
            self.held_jacobian, self.held_drift = np.empty((0, self.J.shape[-1])), np.empty(0)
        self._derived = {}
        for name in LAZY_FIELDS:
            if self.__dict__[name] is None:
                del self.__dict__[name]  # read through ``__getattr__``: ``fill_lazy``

    def __getattr__(self, name: str):
        """A lazily filled field (class docstring) on its first read since the last fill."""
        fill = self.__dict__.get("fill_lazy")
        if name in LAZY_FIELDS and fill is not None:
            self.__dict__.update(fill(self, name))
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def cached(self, key: str, build: Callable[[], object]):
        """``build()``, computed once per fill of these terms and kept under ``key``."""
        if key not in self._derived:
            self._derived[key] = build()
        return self._derived[key]

    def _body(self) -> BodyTerms:
        if self.body is not None:
            return self.body
        return self.cached("body", lambda: self.compute_body(self.q, self.dq))

    @property
    def M_inv(self) -> np.ndarray:
        """M^-1 (nv x nv): the body terms' (``computeMinverse``) when a floating base filled them,
        else computed alone on first use (``compute_inverse_inertia``: ``computeMinverse`` at q,
        or, for an arm's cycle buffer, the Cholesky factor of its M, ``pin.cholesky``)."""
        if self.body is not None:
            return self.body.M_inv
        return self.cached("M_inv", lambda: self.compute_inverse_inertia(self.q))

    @property
    def Jcom(self) -> np.ndarray:
        """The 3 x nv Jacobian of the centre of mass."""
        return self._body().Jcom

    @property
    def dJcom_dq(self) -> np.ndarray:
        """dJcom/dt dq: the centre of mass's acceleration at ddq = 0."""
        return self._body().dJcom_dq

    def frame(self, name: str) -> FrameState:
        """The state of the description's frame ``name`` (its ``frames`` table)."""
        frames = self._body().frames
        if name not in frames:
            raise BadInputError(f"unknown frame {name!r}; the robot's frames: {', '.join(frames) or 'none'}")
        return frames[name]

    @property
    def contact_terms(self) -> np.ndarray:
        """J6, (J J^T)^-1 and the contact point p in one flat array (``contact_views``), what a
        compiled kernel reads in one argument (a kernel's dispatch costs per argument): an arm's
        cycle buffer's is a view of the array its kernel writes at every refill
        (``arm_state``), other terms' is packed on first use, once per fill."""
        if self.cycle_arrays is not None:
            return self.cycle_arrays[4]
        return self.cached("contact_terms", lambda: pack_contact_terms(self.J6, self.JJt_inv, self.contact_point))

    @property
    def locked_body(self) -> np.ndarray:
        """[com, inertia_com (row-major), mass] of the locked robot in one flat array, what the
        compiled crb update reads in one argument: an arm's cycle buffer's is refilled with the
        terms, other terms' is packed on first use, once per fill."""
        if self.cycle_arrays is not None:
            return self.cycle_arrays[5]
        return self.cached("locked_body", lambda: np.concatenate((self.com, np.ravel(self.inertia_com), [self.mass])))

    @property
    def arm_state(self) -> np.ndarray:
        """[J6, (J J^T)^-1, p, dJ6 dq, dq, R, q] in one flat array (``arm_state_views``), what
        the compiled cycle plan reads of an arm's state in one argument: an arm's cycle buffer's
        is the array its kernel writes at every refill, other terms' is packed on first use,
        once per fill."""
        if self.cycle_arrays is not None:
            return self.cycle_arrays[3]
        return self.cached("arm_state", lambda: np.concatenate(
            (self.contact_terms, self.dJ6_dq, self.dq, np.ravel(self.contact_rotation), self.q)
        ))

    @property
    def J_pinv(self) -> np.ndarray:
        """J+ = J^T (J J^T)^-1, the right inverse of J used in (17)."""
        if "J_pinv" not in self._derived:
            self._derived["J_pinv"] = self.J.T @ self.JJt_inv
        return self._derived["J_pinv"]

    @property
    def cond_M(self) -> float:
        if "cond_M" not in self._derived:
            self._derived["cond_M"] = float(np.linalg.cond(self.M))
        return self._derived["cond_M"]

    def refilled(self, pending: tuple[str, ...] = ()) -> ModelTerms:
        """Mark the terms as those of a new state: a new ``stamp``, derived quantities cleared,
        the lazily filled fields ``pending`` left to their first read (class docstring)."""
        self.stamp = next(_FILLS)
        self._derived.clear()
        for name in pending:
            self.__dict__.pop(name, None)
        return self


def symmetric_inverse3(S: np.ndarray) -> tuple[list[list[float]], float]:
    """The inverse of a symmetric 3x3 matrix by its adjugate, in plain floats (no LAPACK call,
    which costs more than the arithmetic at this size), and its determinant."""
    (a, b, c), (_, d, e), (_, _, f) = S.tolist()
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    inv = 1.0 / det
    D, E, F = (a * f - c * c) * inv, (b * c - a * e) * inv, (a * d - b * b) * inv
    A, B, C = A * inv, B * inv, C * inv
    return [[A, B, C], [B, D, E], [C, E, F]], det


@njit(cache=True)
def symmetric_inverse3_into(S, out):
    """Compiled ``symmetric_inverse3`` (for kernels): the inverse of the symmetric 3x3 ``S`` by
    its adjugate into ``out`` (zeros when S is singular); returns det S."""
    a, b, c, d, e, f = S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    inv = 1.0 / det if det != 0.0 else 0.0
    D, E, F = (a * f - c * c) * inv, (b * c - a * e) * inv, (a * d - b * b) * inv
    A, B, C = A * inv, B * inv, C * inv
    out[0, 0], out[0, 1], out[0, 2] = A, B, C
    out[1, 0], out[1, 1], out[1, 2] = B, D, E
    out[2, 0], out[2, 1], out[2, 2] = C, E, F
    return det


ACCEPTED, NEAR_SINGULAR, OUTSIDE_LIMITS, NOT_FINITE = 0, 1, 2, 3
MAX_STATE_ENTRY = 1e100
"""Largest |q_i| (rad) or |dq_i| (rad/s) of a joint state: far above any robot's, far enough
below the float range that the model's products of entries (kinetic energy, Coriolis terms)
cannot overflow."""


@njit(cache=True)
def contact_jacobian_status(J, q, q_min, q_max, check_limits, singular_ratio_squared, JJt_inv):
    """Kernel of the per-state checks: (J J^T)^-1 by its adjugate into ``JJt_inv``, then
    NEAR_SINGULAR when J = 0 or det(J J^T) < ratio^2 trace^3 (with eigenvalues l1 <= l2 <= l3 of J J^T,
    the squared singular values of J, l1 / l3 >= det / trace^3: only then is the exact test
    needed), else OUTSIDE_LIMITS when ``check_limits`` and q leaves [q_min, q_max], else
    ACCEPTED. J J^T in plain loops: a 3 x 3 product is cheaper than a BLAS call, which may
    start threads."""
    S = np.empty((3, 3))
    for i in range(3):
        for j in range(i, 3):
            total = 0.0
            for k in range(J.shape[1]):
                total += J[i, k] * J[j, k]
            S[i, j] = S[j, i] = total
    det = symmetric_inverse3_into(S, JJt_inv)
    trace = S[0, 0] + S[1, 1] + S[2, 2]
    if not (trace > 0.0 and det >= singular_ratio_squared * trace * trace * trace):  # J = 0 too
        return NEAR_SINGULAR
    if check_limits:
        for j in range(q.shape[0]):
            if q[j] < q_min[j] or q[j] > q_max[j]:
                return OUTSIDE_LIMITS
    return ACCEPTED


def arm_cycle_checks(singular_ratio_squared: float, q_min: np.ndarray, q_max: np.ndarray, support: np.ndarray) -> np.ndarray:
    """The packed ``checks`` of ``arm_cycle_terms``, the arm's constants: [s^2, q_min, q_max,
    the support columns] (q_min = -inf and q_max = inf leave the joint limits unchecked;
    s^2 = -inf accepts any contact Jacobian; the columns as floats, exact)."""
    return np.concatenate([[singular_ratio_squared], q_min, q_max, support]).astype(float)


CONTACT_TERMS_EXTRA = 12
"""Values of ``contact_terms`` beyond J6's 6 nv: (J J^T)^-1 (9) and p (3)."""


def pack_contact_terms(J6: np.ndarray, JJt_inv: np.ndarray, contact_point: np.ndarray) -> np.ndarray:
    """[J6, (J J^T)^-1, p], row-major, in a new flat array (``ModelTerms.contact_terms``)."""
    return np.concatenate((np.ravel(J6), np.ravel(JJt_inv), contact_point))


@njit(cache=True)
def contact_views(contact, nv):
    """The views (J6 (6 x nv), (J J^T)^-1 (3 x 3), p (3)) of ``contact`` = [J6, (J J^T)^-1, p]
    (``ModelTerms.contact_terms``, 6 nv + 12 values), for kernels and for Python alike."""
    d = 6 * nv
    return contact[:d].reshape(6, nv), contact[d:d + 9].reshape(3, 3), contact[d + 9:d + 12]


ARM_STATE_EXTRA = CONTACT_TERMS_EXTRA + 15
"""Values of an arm's cycle state beyond J6's 6 nv, dq's nv and q's nq: (J J^T)^-1 (9), p (3),
dJ6 dq (6) and R (9) (``arm_state_views``)."""


@njit(cache=True)
def arm_state_views(state, nv):
    """The views (J6 (6 x nv), (J J^T)^-1 (3 x 3), p (3), dJ6 dq (6), dq (nv), R (3 x 3,
    row-major), q (the rest)) of an arm's cycle state = [J6, (J J^T)^-1, p, dJ6 dq, dq, R, q]
    flat (``arm_cycle_terms``' ``out``, ``ModelTerms.arm_state``): its first 6 nv + 12 values
    are ``ModelTerms.contact_terms`` (``contact_views``)."""
    d = 6 * nv + CONTACT_TERMS_EXTRA
    J6, JJt_inv, p = contact_views(state[:d], nv)
    rotation = state[d + 6 + nv:d + 15 + nv].reshape(3, 3)
    return J6, JJt_inv, p, state[d:d + 6], state[d + 6:d + 6 + nv], rotation, state[d + 15 + nv:]


@njit(cache=True)
def arm_cycle_terms(Jw, dJw, p, rotation, q, dq, checks, out):
    """Kernel of an arm's per-cycle refill, after its ``computeAllTerms``: the contact frame's
    world-aligned Jacobian J6, its drift dJ6 dq and (J J^T)^-1 from Pinocchio's own arrays, the
    state and the contact rotation copied beside them, and the state's status.

    Jw (6 x nv) are Pinocchio's world-frame joint Jacobians (spatial velocities at the world
    origin, linear then angular: ``data.J``), dJw their time variation (``data.dJ``), p and
    ``rotation`` the contact frame's placement (world; Pinocchio's column-major R), (q, dq) the
    state (writable row-major arrays: one compiled signature); ``checks`` = [s^2, q_min, q_max,
    the support columns] (``arm_cycle_checks``: the columns of the velocities that move the
    contact frame); ``out`` = [J6, (J J^T)^-1, p, dJ6 dq, dq, R, q] flat (``arm_state_views``,
    R row-major). A point p of the body moves at v_p = v_O + w x p, so on the support columns
    J6 = [Jw_lin + Jw_ang x p; Jw_ang] (zeros elsewhere) and, with (a_O, dw) = dJw dq at
    ddq = 0, dJ6 dq = [a_O + dw x p + w x v_p; dw] (the frame's classical acceleration).
    Returns NOT_FINITE when sum |q_i| + sum |dq_i| exceeds MAX_STATE_ENTRY (nq + nv) (a NaN, an
    infinity or a huge entry: ``check_state``'s test), else NEAR_SINGULAR when J = 0 or det(J J^T) <
    s^2 trace(J J^T)^3 (``contact_jacobian_status``'s bound), else OUTSIDE_LIMITS when q leaves
    [q_min, q_max], else ACCEPTED, the only case that writes ``out``. Plain loops, no allocation."""
    nq, nv = q.shape[0], dq.shape[0]
    support = checks[1 + 2 * nq:]
    total = 0.0
    for j in range(nq):
        total += abs(q[j])
    for j in range(nv):
        total += abs(dq[j])
    if not total <= (nq + nv) * MAX_STATE_ENTRY:
        return NOT_FINITE
    px, py, pz = p[0], p[1], p[2]
    s00, s01, s02, s11, s12, s22 = linear_gram(Jw, p, support)
    A, B, C = s11 * s22 - s12 * s12, s02 * s12 - s01 * s22, s01 * s12 - s02 * s11
    det = s00 * A + s01 * B + s02 * C
    trace = s00 + s11 + s22
    if not (trace > 0.0 and det >= checks[0] * trace * trace * trace):  # J = 0 too
        return NEAR_SINGULAR
    for j in range(nq):
        if q[j] < checks[1 + j] or q[j] > checks[1 + nq + j]:
            return OUTSIDE_LIMITS
    out[: 6 * nv] = 0.0
    vx = vy = vz = wx = wy = wz = ax = ay = az = bx = by = bz = 0.0
    for c in range(support.shape[0]):
        k = int(support[c])
        out[k] = Jw[0, k] + Jw[4, k] * pz - Jw[5, k] * py
        out[nv + k] = Jw[1, k] + Jw[5, k] * px - Jw[3, k] * pz
        out[2 * nv + k] = Jw[2, k] + Jw[3, k] * py - Jw[4, k] * px
        out[3 * nv + k], out[4 * nv + k], out[5 * nv + k] = Jw[3, k], Jw[4, k], Jw[5, k]
        v = dq[k]
        vx += Jw[0, k] * v
        vy += Jw[1, k] * v
        vz += Jw[2, k] * v
        wx += Jw[3, k] * v
        wy += Jw[4, k] * v
        wz += Jw[5, k] * v
        ax += dJw[0, k] * v
        ay += dJw[1, k] * v
        az += dJw[2, k] * v
        bx += dJw[3, k] * v
        by += dJw[4, k] * v
        bz += dJw[5, k] * v
    vx, vy, vz = vx + wy * pz - wz * py, vy + wz * px - wx * pz, vz + wx * py - wy * px  # v_p
    d = 6 * nv
    inv = 1.0 / det
    D, E, F = (s00 * s22 - s02 * s02) * inv, (s01 * s02 - s00 * s12) * inv, (s00 * s11 - s01 * s01) * inv
    A, B, C = A * inv, B * inv, C * inv
    out[d], out[d + 1], out[d + 2] = A, B, C
    out[d + 3], out[d + 4], out[d + 5] = B, D, E
    out[d + 6], out[d + 7], out[d + 8] = C, E, F
    out[d + 9], out[d + 10], out[d + 11] = px, py, pz
    d += CONTACT_TERMS_EXTRA
    out[d] = ax + by * pz - bz * py + wy * vz - wz * vy
    out[d + 1] = ay + bz * px - bx * pz + wz * vx - wx * vz
    out[d + 2] = az + bx * py - by * px + wx * vy - wy * vx
    out[d + 3], out[d + 4], out[d + 5] = bx, by, bz
    d += 6
    out[d:d + nv] = dq
    d += nv
    for i in range(3):
        for j in range(3):
            out[d + 3 * i + j] = rotation[i, j]
    out[d + 9:] = q
    return ACCEPTED


@njit(cache=True)
def linear_gram(Jw, p, support):
    """Kernel of ``arm_cycle_terms``: the upper triangle (s00, s01, s02, s11, s12, s22) of J J^T,
    J = Jw_lin + Jw_ang x p the linear rows of the contact frame's Jacobian on the support columns."""
    px, py, pz = p[0], p[1], p[2]
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    for c in range(support.shape[0]):
        k = int(support[c])
        x = Jw[0, k] + Jw[4, k] * pz - Jw[5, k] * py
        y = Jw[1, k] + Jw[5, k] * px - Jw[3, k] * pz
        z = Jw[2, k] + Jw[3, k] * py - Jw[4, k] * px
        s00 += x * x
        s01 += x * y
        s02 += x * z
        s11 += y * y
        s12 += y * z
        s22 += z * z
    return s00, s01, s02, s11, s12, s22


@njit(cache=True)
def mirror_upper(upper, out):
    """Kernel: out = the symmetric matrix whose upper triangle is ``upper``'s (Pinocchio fills
    only the upper triangles of M and M^-1)."""
    n = upper.shape[0]
    for i in range(n):
        for j in range(i, n):
            out[i, j] = upper[i, j]
            out[j, i] = upper[i, j]
