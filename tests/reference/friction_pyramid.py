"""Plain-numpy statements of the compiled friction-row kernels (``controller.model.friction_pyramid``)."""

import numpy as np

from impactqp.controller.model.friction_pyramid import EDGE_GUARD, SLIP_SECTOR, SLIP_SPEED, EdgeMatrices


def reference_edge_impulse_maps(W, normal, directions, restitution) -> np.ndarray:
    """G_i = -(1 + c_r) d_i n^T / max(n^T W d_i, kappa n^T W n) (edges x 3 x 3)."""
    denominators = np.maximum(directions @ (W.T @ normal), EDGE_GUARD * (normal @ W @ normal))
    return -(1.0 + restitution) * np.einsum("ea,b->eab", directions, normal) / denominators[:, None, None]


def reference_edge_matrices(J, K, W, normal, directions, restitution) -> EdgeMatrices:
    """``edge_matrices_into``: A_i = K G_i J and P_i = J^T G_i J."""
    G = reference_edge_impulse_maps(W, normal, directions, restitution)
    return EdgeMatrices(K @ G @ J, J.T @ G @ J)


def reference_slip_edges(velocity, W, normal, friction, restitution, uncertain) -> np.ndarray:
    """``slip_edges_into``: the sector's edges n - mu / cos(alpha / 2) (cos(theta) s + sin(theta) n x s),
    theta in (-alpha, 0, alpha), when the slip is certain, else ``uncertain`` (the 3-edge pyramid)."""
    P = np.eye(3) - np.outer(normal, normal)
    u_n, v_t = normal @ velocity, P @ velocity
    speed = np.linalg.norm(v_t)
    rate = normal @ W @ normal - friction * np.linalg.norm(P @ W.T @ normal)
    if speed < SLIP_SPEED or rate <= 0.0:
        return uncertain.copy()
    impulse = (1.0 + np.sqrt(2.0) * restitution) * max(-u_n, 0.0) / rate
    drift = (np.linalg.norm(P @ W @ normal) + friction * np.linalg.norm(P @ W @ P)) * impulse
    if drift > speed * np.sin(SLIP_SECTOR):
        return uncertain.copy()
    s = v_t / speed
    angles = SLIP_SECTOR * np.array([-1.0, 0.0, 1.0])
    tangents = np.cos(angles)[:, None] * s + np.sin(angles)[:, None] * np.cross(normal, s)
    return normal - friction / np.cos(SLIP_SECTOR / 2) * tangents
