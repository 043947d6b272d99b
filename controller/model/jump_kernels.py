"""The compiled kernels (numba) of the jump maps of ``controller.model.jump`` (docs/predictors.md).

Two forms of the same predictors, A = K G J the jump matrix, P = J^T G J the impulse-torque
matrix, G the impulse map:

- no held contact (a fixed-base arm): the CRB maps (``crb_maps``), one CRB prediction
  (``crb_jump``), W_crb n
  (``crb_inverse_inertia_times``) and the rank-one A and P of the normal-impulse models (12)
  from W n alone (``rank_one_jump_matrices``), J+ = J^T (J J^T)^-1 (17);
- held contacts (a humanoid's soles, Jacobian Jf: bilateral, they stay still through the
  impact, M dv = J^T iota + Jf^T lambda, Jf dv = 0): ``held_contact_maps`` from M^-1 with the
  constrained inverse inertia P_f = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 in place of M^-1,
  W_gm = J P_f J^T, and the held-contact right inverse J# = N J^T (J N J^T)^-1 in place of J+
  (N = I - Jf^T (Jf Jf^T)^-1 Jf, the projector onto the null space of Jf), plus the centre-of-mass
  jump map C = Jcom P_f J^T. With Jf empty, P_f = M^-1 and J# = J+: the first form.

Small products are written as loops (``product``, ``product_t``): BLAS would start threads for
these small matrices, which costs more than the product on a loaded machine.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .model_terms import symmetric_inverse3_into
from .term_fills import SingularPostureError

HELD_CONTACT_METHODS = ("classical", "gm", "crb")
"""The predictors with held contacts, in the order of ``held_contact_maps``' method codes."""
CLASSICAL, CRB = HELD_CONTACT_METHODS.index("classical"), HELD_CONTACT_METHODS.index("crb")


@njit(cache=True)
def crb_inverse_inertia_times(contact_point, com, inertia_com, mass, normal):
    """Kernel of ``CompositeRigidBodyJump.inverse_inertia_times``: W_crb n (20), with I_c^-1
    by the adjugate (``symmetric_inverse3_into``)."""
    rx, ry, rz = contact_point[0] - com[0], contact_point[1] - com[1], contact_point[2] - com[2]
    nx, ny, nz = normal[0], normal[1], normal[2]
    ax, ay, az = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx  # r x n
    Iinv = np.empty((3, 3))
    symmetric_inverse3_into(inertia_com, Iinv)
    bx = Iinv[0, 0] * ax + Iinv[0, 1] * ay + Iinv[0, 2] * az
    by = Iinv[1, 0] * ax + Iinv[1, 1] * ay + Iinv[1, 2] * az
    bz = Iinv[2, 0] * ax + Iinv[2, 1] * ay + Iinv[2, 2] * az
    out = np.empty(3)
    out[0] = nx / mass - (ry * bz - rz * by)
    out[1] = ny / mass - (rz * bx - rx * bz)
    out[2] = nz / mass - (rx * by - ry * bx)
    return out


@njit(cache=True)
def welded_inverse_inertia(contact_point, com, inertia_com, mass):
    """Kernel: W_crb = I3 / m - [r]x I_c^-1 [r]x (20), r = contact point - CoM, in a new array
    (``welded_inverse_inertia_into``); the compiled twin of :func:`crb_inverse_inertia` for the
    arm's and the standing humanoid's kernels."""
    W = np.empty((3, 3))
    welded_inverse_inertia_into((contact_point, com, inertia_com, mass), W)
    return W


@njit(cache=True, inline="always")
def welded_inverse_inertia_into(rigid, W):
    """Kernel: W_crb (20) of rigid = (contact point, CoM, centroidal inertia, mass) into W, with
    I_c^-1 by the adjugate of the symmetric I_c and [r]x I_c^-1 [r]x column by column in plain
    floats (no array allocated: a batch calls it for every state), symmetrized."""
    contact_point, com, S, mass = rigid
    r = (contact_point[0] - com[0], contact_point[1] - com[1], contact_point[2] - com[2])
    a, b, c, d, e, f = S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    inv = 1.0 / det if det != 0.0 else 0.0
    Iinv = (A * inv, B * inv, C * inv, B * inv, (a * f - c * c) * inv, (b * c - a * e) * inv,
            C * inv, (b * c - a * e) * inv, (a * d - b * b) * inv)
    K = (0.0, -r[2], r[1], r[2], 0.0, -r[0], -r[1], r[0], 0.0)  # [r]x
    for j in range(3):  # column j: e_j / m - r x (I_c^-1 (r x e_j)), r x e_j = [r]x e_j
        u = (K[j], K[3 + j], K[6 + j])
        v0 = Iinv[0] * u[0] + Iinv[1] * u[1] + Iinv[2] * u[2]
        v1 = Iinv[3] * u[0] + Iinv[4] * u[1] + Iinv[5] * u[2]
        v2 = Iinv[6] * u[0] + Iinv[7] * u[1] + Iinv[8] * u[2]
        W[0, j] = -(r[1] * v2 - r[2] * v1)
        W[1, j] = -(r[2] * v0 - r[0] * v2)
        W[2, j] = -(r[0] * v1 - r[1] * v0)
        W[j, j] += 1.0 / mass
    for i in range(3):
        for j in range(i):
            W[i, j] = W[j, i] = 0.5 * (W[i, j] + W[j, i])


@njit(cache=True)
def crb_maps(contact_point, com, inertia_com, mass, J, JJt_inv, normal, restitution):
    """Kernel of ``CompositeRigidBodyJump.unit_maps``: W_crb (20, ``welded_inverse_inertia``);
    G = -(1+c_r) n n^T / (n^T W_crb n) (12); K = J^T (J J^T)^-1 W_crb (21). Returns (G, K, W)."""
    W = welded_inverse_inertia(contact_point, com, inertia_com, mass)
    Wn = W @ normal
    scale = -(1.0 + restitution) / (normal @ Wn)
    G = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            G[i, j] = scale * normal[i] * normal[j]
    K = J.T @ (JJt_inv @ W)
    return G, K, W


@njit(cache=True, inline="always")
def crb_jump(rigid, J, JJt_inv, impact, outputs):
    """Kernel of ``CompositeRigidBodyJump.predict``: W_crb (20, ``welded_inverse_inertia_into``,
    rigid = (contact point, CoM, centroidal inertia, mass)), the impulse
    iota = -(1+c_r) n (n.v-) / (n^T W_crb n) (12) and the jump J^T (J J^T)^-1 W_crb iota (21), in
    plain loops, for impact = (unit normal n, v-, c_r), into outputs = (jump, iota, W_crb)."""
    normal, velocity, restitution = impact
    jump, impulse, W = outputs
    welded_inverse_inertia_into(rigid, W)
    Wn0 = W[0, 0] * normal[0] + W[0, 1] * normal[1] + W[0, 2] * normal[2]
    Wn1 = W[1, 0] * normal[0] + W[1, 1] * normal[1] + W[1, 2] * normal[2]
    Wn2 = W[2, 0] * normal[0] + W[2, 1] * normal[1] + W[2, 2] * normal[2]
    normal_Wn = normal[0] * Wn0 + normal[1] * Wn1 + normal[2] * Wn2
    normal_v = normal[0] * velocity[0] + normal[1] * velocity[1] + normal[2] * velocity[2]
    scale = -(1.0 + restitution) * normal_v / normal_Wn
    for i in range(3):
        impulse[i] = scale * normal[i]
    y0 = scale * (JJt_inv[0, 0] * Wn0 + JJt_inv[0, 1] * Wn1 + JJt_inv[0, 2] * Wn2)  # (J J^T)^-1 W iota
    y1 = scale * (JJt_inv[1, 0] * Wn0 + JJt_inv[1, 1] * Wn1 + JJt_inv[1, 2] * Wn2)
    y2 = scale * (JJt_inv[2, 0] * Wn0 + JJt_inv[2, 1] * Wn1 + JJt_inv[2, 2] * Wn2)
    for k in range(J.shape[1]):
        jump[k] = J[0, k] * y0 + J[1, k] * y1 + J[2, k] * y2


@njit(cache=True)
def rank_one_jump_matrices(J, JJt_inv, W_normal, normal, restitution, jump_matrix, torque_matrix, impulse_map):
    """Kernel of ``GeneralizedMomentumJump.fixed_base_matrices``: A = s (J^T (J J^T)^-1 W n)(J^T n)^T,
    P = s (J^T n)(J^T n)^T and G = s n n^T with s = -(1+c_r) / (n^T W n), written into the three
    matrices. Plain loops: at these sizes a BLAS call from compiled code costs more than its
    arithmetic."""
    s = -(1.0 + restitution) / (normal[0] * W_normal[0] + normal[1] * W_normal[1] + normal[2] * W_normal[2])
    y0 = s * (JJt_inv[0, 0] * W_normal[0] + JJt_inv[0, 1] * W_normal[1] + JJt_inv[0, 2] * W_normal[2])
    y1 = s * (JJt_inv[1, 0] * W_normal[0] + JJt_inv[1, 1] * W_normal[1] + JJt_inv[1, 2] * W_normal[2])
    y2 = s * (JJt_inv[2, 0] * W_normal[0] + JJt_inv[2, 1] * W_normal[1] + JJt_inv[2, 2] * W_normal[2])
    nv = J.shape[1]
    direction, Jt_normal = np.empty(nv), np.empty(nv)  # J^T (J J^T)^-1 s W n and J^T n
    for k in range(nv):
        direction[k] = J[0, k] * y0 + J[1, k] * y1 + J[2, k] * y2
        Jt_normal[k] = normal[0] * J[0, k] + normal[1] * J[1, k] + normal[2] * J[2, k]
    for i in range(nv):
        for j in range(nv):
            jump_matrix[i, j] = direction[i] * Jt_normal[j]
            torque_matrix[i, j] = s * Jt_normal[i] * Jt_normal[j]
    for i in range(3):
        for j in range(3):
            impulse_map[i, j] = s * normal[i] * normal[j]


@njit(cache=True)
def held_contact_maps(M_inv, J6, Jf, Jcom, rigid, method, normal, c_r):
    """Kernel: (A, P, G, C) of ``held_contact_maps_into`` in new arrays."""
    n = J6.shape[1]
    out = (np.empty((n, n)), np.empty((n, n)), np.empty((3, 3)), np.empty((3, 3)), np.empty((Jf.shape[0], 3)))
    held_contact_maps_into((M_inv, J6, Jf, Jcom), rigid, method, (normal, c_r), out)
    return out[0], out[1], out[2], out[3]


@njit(cache=True)
def held_contact_maps_into(terms, rigid, method, impact, out):
    """Kernel: (A = K G J, P = J^T G J, G, C = Jcom P_f J^T) (module docstring) of the method
    ``HELD_CONTACT_METHODS[method]`` and the held contacts' impulse map Z, written into
    out = (A, P, G, C, Z), for terms = (M^-1, J6, Jf, Jcom), rigid = (contact point, CoM,
    centroidal inertia, mass) for W_crb (20, ``welded_inverse_inertia``) and impact = (n, c_r):

        classical  (5)-(6)           G = -(1 + c_r) W_gm^-1,                  K = P_f J^T
        gm         (12), (22)-(23)   G = -(1 + c_r) n n^T / (n^T W_gm n),     K = J# W_gm
        crb        (12), (20)-(21)   G = -(1 + c_r) n n^T / (n^T W_crb n),    K = J# W_crb

    Never forms P_f: with Y_f = Jf M^-1 and Y_J = J M^-1 (M^-1 symmetric),
    Z = (Jf M^-1 Jf^T)^-1 Jf M^-1 J^T = (Jf Y_f^T)^-1 Jf Y_J^T, the held contacts' impulsive
    wrenches lambda = -Z iota (``jump.held_impulse``), and (P_f J^T)^T = Y_J - Z^T Y_f;
    (N J^T)^T = J - ((Jf Jf^T)^-1 Jf J^T)^T Jf. The normal-impulse models' A and P are rank one
    (12): A = s (K n)(J^T n)^T, P = s (J^T n)(J^T n)^T, s = -(1 + c_r) / (n^T W n), with
    K n = (N J^T) (J N J^T)^-1 W n. With no held contact (Jf of no rows), (P_f J^T)^T = Y_J,
    (N J^T)^T = J and Z has no rows. The products skip Jf's and J's zero entries (a foot's row
    moves the base and one leg) and run along rows (``product``); SingularPostureError when Jf M^-1 Jf^T
    or Jf Jf^T is singular (``held_solve``)."""
    M_inv, J6, Jf, Jcom = terms
    normal, c_r = impact
    A, P, G, C, Z = out
    J = np.ascontiguousarray(J6[:3])
    PJt_T = product(J, M_inv)  # Y_J, then (P_f J^T)^T
    NJt_T = J.copy()
    if Jf.shape[0] > 0:
        Yf = product(Jf, M_inv)
        Z[:] = product(Jf, np.ascontiguousarray(PJt_T.T))
        held_solve(product(Jf, np.ascontiguousarray(Yf.T)), Z)
        subtract_t_product(Z, Yf, PJt_T)
        JfJt = product(Jf, np.ascontiguousarray(J.T))
        held_solve(product(Jf, np.ascontiguousarray(Jf.T)), JfJt)
        subtract_t_product(JfJt, Jf, NJt_T)
    C[:] = product_t(Jcom, PJt_T)
    if method == CLASSICAL:
        symmetric_inverse3_into(symmetric_part(product_t(J, PJt_T)), G)
        G *= -(1.0 + c_r)
        GJ = product(G, J)
        for i in range(J.shape[1]):
            for j in range(J.shape[1]):
                A[i, j] = PJt_T[0, i] * GJ[0, j] + PJt_T[1, i] * GJ[1, j] + PJt_T[2, i] * GJ[2, j]
                P[i, j] = J[0, i] * GJ[0, j] + J[1, i] * GJ[1, j] + J[2, i] * GJ[2, j]
        return
    W = welded_inverse_inertia(*rigid) if method == CRB else symmetric_part(product_t(J, PJt_T))
    JNJt_inv = np.empty((3, 3))
    symmetric_inverse3_into(symmetric_part(product_t(J, NJt_T)), JNJt_inv)
    Wn = product(W, normal.reshape((3, 1)))
    s = -(1.0 + c_r) / (normal[0] * Wn[0, 0] + normal[1] * Wn[1, 0] + normal[2] * Wn[2, 0])
    for i in range(3):
        for j in range(3):
            G[i, j] = s * normal[i] * normal[j]
    y = product(JNJt_inv, Wn)[:, 0]
    Jt_normal = product(normal.reshape((1, 3)), J)[0]
    for i in range(J.shape[1]):
        direction = s * (NJt_T[0, i] * y[0] + NJt_T[1, i] * y[1] + NJt_T[2, i] * y[2])  # s (K n)_i
        torque = s * Jt_normal[i]
        for j in range(J.shape[1]):
            A[i, j] = direction * Jt_normal[j]
            P[i, j] = torque * Jt_normal[j]


@njit(cache=True)
def held_solve(S, B):
    """Kernel: B <- S^-1 B for a symmetric positive-definite S (Jf M^-1 Jf^T or Jf Jf^T:
    ``cholesky_solve_in_place``, S overwritten); SingularPostureError when S is singular."""
    if not cholesky_solve_in_place(S, B):
        raise SingularPostureError("the held contacts' Jacobian is singular at this state")


@njit(cache=True)
def cholesky_solve_in_place(S, B):
    """Kernel: B <- S^-1 B for a symmetric S by its Cholesky factor S = L L^T (L written over
    S's lower triangle, its upper triangle read only on the diagonal), then forward and back
    substitution; False when a pivot L_jj^2 is not above 1e-12 times S's largest diagonal entry
    (S singular, or not positive definite, for this purpose)."""
    size = S.shape[0]
    scale = 0.0
    for i in range(size):
        scale = max(scale, abs(S[i, i]))
    for j in range(size):
        pivot = S[j, j]
        for k in range(j):
            pivot -= S[j, k] * S[j, k]
        if not pivot > 1e-12 * scale:
            return False
        pivot = np.sqrt(pivot)
        S[j, j] = pivot
        for i in range(j + 1, size):
            total = S[i, j]
            for k in range(j):
                total -= S[i, k] * S[j, k]
            S[i, j] = total / pivot
    for c in range(B.shape[1]):
        for i in range(size):  # L y = b
            total = B[i, c]
            for k in range(i):
                total -= S[i, k] * B[k, c]
            B[i, c] = total / S[i, i]
        for i in range(size - 1, -1, -1):  # L^T x = y
            total = B[i, c]
            for k in range(i + 1, size):
                total -= S[k, i] * B[k, c]
            B[i, c] = total / S[i, i]
    return True


@njit(cache=True)
def subtract_t_product(X, Y, out):
    """Kernel: out -= X^T Y in plain loops (X: k x r, Y: k x n, out: r x n)."""
    for a in range(X.shape[0]):
        for r in range(X.shape[1]):
            x = X[a, r]
            for j in range(Y.shape[1]):
                out[r, j] -= x * Y[a, j]


@njit(cache=True)
def symmetric_part(S):
    """Kernel: (S + S^T) / 2 in a new array."""
    return 0.5 * (S + S.T)


@njit(cache=True)
def product(A, B):
    """Kernel: the matrix product A B in plain loops, skipping A's zero entries (a foot's
    Jacobian row has entries for the base and one leg only)."""
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


@njit(cache=True)
def solve_in_place(A, B):
    """Kernel: B <- A^-1 B by Gaussian elimination with partial pivoting (A overwritten); False
    when a pivot is below 1e-12 times A's largest entry (A singular for this purpose)."""
    size = A.shape[0]
    scale = 0.0
    for i in range(size):
        for j in range(size):
            scale = max(scale, abs(A[i, j]))
    for col in range(size):
        pivot = col
        for i in range(col + 1, size):
            if abs(A[i, col]) > abs(A[pivot, col]):
                pivot = i
        if not abs(A[pivot, col]) > 1e-12 * scale:
            return False
        if pivot != col:
            for j in range(size):
                A[col, j], A[pivot, j] = A[pivot, j], A[col, j]
            for j in range(B.shape[1]):
                B[col, j], B[pivot, j] = B[pivot, j], B[col, j]
        for i in range(col + 1, size):
            factor = A[i, col] / A[col, col]
            if factor == 0.0:
                continue
            for j in range(col, size):
                A[i, j] -= factor * A[col, j]
            for j in range(B.shape[1]):
                B[i, j] -= factor * B[col, j]
    for col in range(size - 1, -1, -1):
        for j in range(B.shape[1]):
            total = B[col, j]
            for i in range(col + 1, size):
                total -= A[col, i] * B[i, j]
            B[col, j] = total / A[col, col]
    return True
