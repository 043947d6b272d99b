"""The classical prediction's joint-space matrices of a fixed base in one compiled call
(``jump.ClassicalJump.fixed_base_matrices`` and an arm's expected impact, every cycle).

Classical prediction, eqs. (5)-(6) (``jump``'s table): G = -(1+c_r) W_gm^-1 with
W_gm = J M^-1 J^T (22), K = M^-1 J^T, so that

    A = K G J = M^-1 J^T G J,    P = J^T G J,

the jump dq_jump = A dq- and the impulse torque J^T iota = P dq- of the pre-impact velocity dq-.
M^-1 is the terms' (Pinocchio's ``computeMinverse``); W_gm is inverted by LU (LAPACK).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def classical_jump_matrices(M_inv, J, restitution, jump_matrix, torque_matrix, impulse_map):
    """Kernel: A = M^-1 J^T G J, P = J^T G J and G = -(1+c_r) (J M^-1 J^T)^-1 (module docstring),
    written into the three matrices (M^-1 symmetric)."""
    n = J.shape[1]
    MinvJt = np.empty((n, 3))
    for i in range(n):
        for a in range(3):
            total = 0.0
            for k in range(n):
                total += M_inv[i, k] * J[a, k]
            MinvJt[i, a] = total
    W = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            total = 0.0
            for k in range(n):
                total += J[a, k] * MinvJt[k, b]
            W[a, b] = total
    G = np.linalg.inv(W)
    GJ = np.empty((3, n))
    for a in range(3):
        for b in range(3):
            G[a, b] *= -(1.0 + restitution)
            impulse_map[a, b] = G[a, b]
    for a in range(3):
        for j in range(n):
            GJ[a, j] = G[a, 0] * J[0, j] + G[a, 1] * J[1, j] + G[a, 2] * J[2, j]
    for i in range(n):
        for j in range(n):
            jump_matrix[i, j] = MinvJt[i, 0] * GJ[0, j] + MinvJt[i, 1] * GJ[1, j] + MinvJt[i, 2] * GJ[2, j]
            torque_matrix[i, j] = J[0, i] * GJ[0, j] + J[1, i] * GJ[1, j] + J[2, i] * GJ[2, j]
