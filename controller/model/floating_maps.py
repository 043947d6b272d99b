"""The floating-base predictors as linear maps of the contact velocity (docs/whole-body-qp.md).

Every predictor of ``floating_base`` (feet held) is linear in the pre-impact contact velocity
v- = J v: the hand impulse is iota = G v- and the generalized-velocity jump dv = K iota, so
dv = A v with A = K G J (nv x nv), the floating-base twin of the arm's ``JumpMatrices``:

    classical  (5)-(6)           G = -(1 + c_r) W_gm^-1,                  K = P J^T
    gm         (12), (22)-(23)   G = -(1 + c_r) n n^T / (n^T W_gm n),     K = J# W_gm
    crb        (12), (20)-(21)   G = -(1 + c_r) n n^T / (n^T W_crb n),    K = J# W_crb

with the constrained inverse inertia P = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1,
W_gm = J P J^T, W_crb the welded robot's contact inverse inertia and the feet-held right inverse
J# = N (J N)^+ = N J^T (J N J^T)^-1 (N = I - Jf^T (Jf Jf^T)^-1 Jf the symmetric, idempotent
projector onto the null space of Jf; J N of full row rank). The centre-of-mass velocity jumps by
C iota, C = Jcom P J^T (``capture.com_jump_map``): the momentum balance with the feet held.

Computed here in one compiled kernel from M^-1 with small dense products and solves (the
``floating_base`` functions factor M with multi-right-hand-side LAPACK solves, which a control
cycle cannot afford on a loaded machine); the tests check both give the same maps.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .floating_base import METHODS
from .jump import welded_inverse_inertia
from .validation import BadInputError
from .whole_body_terms import WholeBodyTerms

CLASSICAL, CRB = METHODS.index("classical"), METHODS.index("crb")  # the kernel's method codes


class FloatingJumpMaps(NamedTuple):
    """G (3 x 3: iota = G v-), A = K G J (nv x nv: dv = A v) and C (3 x 3: dc jump = C iota)."""

    impulse_map: np.ndarray
    jump_matrix: np.ndarray
    com_map: np.ndarray


def floating_jump_maps(terms: WholeBodyTerms, method: str, normal: np.ndarray, c_r: float) -> FloatingJumpMaps:
    """The maps of ``method`` (module docstring) for the unit surface normal ``normal`` and the
    restitution c_r (both already checked)."""
    if method not in METHODS:
        raise BadInputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    rigid = (terms.contact_point, terms.com, terms.inertia_com, terms.mass)
    return FloatingJumpMaps(
        *jump_maps_kernel(terms.M_inv, terms.J6, terms.Jf, terms.Jcom, rigid, METHODS.index(method), normal, c_r)
    )


@njit(cache=True)
def jump_maps_kernel(M_inv, J6, Jf, Jcom, rigid, method, normal, c_r):
    """Kernel: (G, A = K G J, C = Jcom P J^T) (module docstring) of the method
    ``METHODS[method]``, rigid = (contact point, CoM, centroidal inertia, mass) for W_crb (20,
    ``jump.welded_inverse_inertia``).
    Never forms P: with Y = [Jf; J] M^-1 (M^-1 symmetric), (P J^T)^T = Y_J - Z^T Y_f,
    Z = (Jf M^-1 Jf^T)^-1 Jf M^-1 J^T; products as row dot products (``product_t``)."""
    J = np.ascontiguousarray(J6[:3])
    Y = product(np.vstack((Jf, J)), M_inv)
    Yf, YJ = Y[:12], Y[12:]
    Z = np.linalg.solve(product_t(Jf, Yf), product_t(Jf, YJ))
    PJt_T = YJ - product(np.ascontiguousarray(Z.T), Yf)
    W = product_t(J, PJt_T)
    W = np.ascontiguousarray(0.5 * (W + W.T))
    if method == CLASSICAL:
        G = np.ascontiguousarray(-(1.0 + c_r) * np.linalg.inv(W))
        K_T = PJt_T
    else:
        if method == CRB:
            W = welded_inverse_inertia(*rigid)
        G = (-(1.0 + c_r) / np.sum(np.outer(normal, normal) * W)) * np.outer(normal, normal)
        # (N J^T)^T = J - (Jf J^T)^T (Jf Jf^T)^-1 Jf, K^T = ((J N J^T)^-1 W)^T (N J^T)^T
        NJt_T = J - product(np.ascontiguousarray(np.linalg.solve(product_t(Jf, Jf), product_t(Jf, J)).T), Jf)
        K_T = product(np.ascontiguousarray(np.linalg.solve(product_t(J, NJt_T), W).T), NJt_T)
    GJ = product(G, J)
    return G, product(np.ascontiguousarray(K_T.T), GJ), product_t(Jcom, PJt_T)


@njit(cache=True)
def product(A, B):
    """Kernel: the matrix product A B in plain loops (BLAS would start threads for these small
    matrices, which costs more than the product on a loaded machine), skipping A's zero entries
    (a foot's Jacobian row has entries for the base and one leg only)."""
    rows, inner = A.shape
    out = np.zeros((rows, B.shape[1]))
    for i in range(rows):
        for k in range(inner):
            a = A[i, k]
            if a == 0.0:
                continue
            for j in range(B.shape[1]):
                out[i, j] += a * B[k, j]
    return out


@njit(cache=True)
def product_t(A, B):
    """Kernel: A B^T in plain loops, each entry the dot product of two rows."""
    out = np.empty((A.shape[0], B.shape[0]))
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            total = 0.0
            for k in range(A.shape[1]):
                total += A[i, k] * B[j, k]
            out[i, j] = total
    return out
