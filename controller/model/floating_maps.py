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

Computed here from M^-1 with small dense products and solves (the ``floating_base`` functions
factor M with multi-right-hand-side LAPACK solves, which a control cycle cannot afford on a
loaded machine); the tests check both give the same maps.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .floating_base import METHODS, crb_inverse_inertia
from .validation import BadInputError
from .whole_body_terms import WholeBodyTerms


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
    J, Jf = terms.J, terms.Jf
    MiJf = terms.M_inv @ Jf.T
    P = terms.M_inv - MiJf @ np.linalg.solve(Jf @ MiJf, MiJf.T)
    PJt = P @ J.T
    W_gm = J @ PJt
    W_gm = 0.5 * (W_gm + W_gm.T)
    if method == "classical":
        G = -(1.0 + c_r) * np.linalg.inv(W_gm)
        K = PJt
    else:
        W = W_gm if method == "gm" else crb_inverse_inertia(terms)
        G = (-(1.0 + c_r) / (normal @ W @ normal)) * np.outer(normal, normal)
        K = feet_held_pinv(J, Jf) @ W
    return FloatingJumpMaps(G, K @ (G @ J), terms.Jcom @ PJt)


def feet_held_pinv(J: np.ndarray, Jf: np.ndarray) -> np.ndarray:
    """J# = N J^T (J N J^T)^-1 (module docstring): the least-norm dv with J dv = x, Jf dv = 0."""
    NJt = J.T - Jf.T @ np.linalg.solve(Jf @ Jf.T, Jf @ J.T)
    return NJt @ np.linalg.inv(J @ NJt)
