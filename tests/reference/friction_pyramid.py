"""Plain-numpy statements of the compiled friction-row kernels (``controller.model.friction_pyramid``)."""

import numpy as np

from impactqp.controller.model.friction_pyramid import EDGE_GUARD, SLIP_SPEED, EdgeMatrices


def reference_edge_impulse_maps(W, normal, directions, restitution) -> np.ndarray:
    """G_i = -(1 + c_r) d_i n^T / max(n^T W d_i, kappa n^T W n) (edges x 3 x 3)."""
    denominators = np.maximum(directions @ (W.T @ normal), EDGE_GUARD * (normal @ W @ normal))
    return -(1.0 + restitution) * np.einsum("ea,b->eab", directions, normal) / denominators[:, None, None]


def reference_edge_matrices(J, K, W, normal, directions, restitution) -> EdgeMatrices:
    """``edge_matrices_into``: A_i = K G_i J and P_i = J^T G_i J."""
    G = reference_edge_impulse_maps(W, normal, directions, restitution)
    return EdgeMatrices(K @ G @ J, J.T @ G @ J)


def reference_slip_direction(J, dq, normal, friction) -> np.ndarray:
    """``slip_direction_into``: n - mu v_t / |v_t| for v = J dq, or n below ``SLIP_SPEED``."""
    v = J @ dq
    v_t = v - (normal @ v) * normal
    speed = np.linalg.norm(v_t)
    return normal - friction * v_t / speed if speed >= SLIP_SPEED else normal.copy()
