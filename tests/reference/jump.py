"""Plain-numpy statements of the compiled jump kernels (``controller.model.jump_kernels``)."""

import numpy as np

from impactqp.controller.model.jump import JumpMaps, JumpMatrices, crb_inverse_inertia, normal_impulse_map
from impactqp.controller.model.model_terms import symmetric_inverse3


def reference_crb_unit_maps(terms, normal, restitution) -> JumpMaps:
    """``CompositeRigidBodyJump.unit_maps``: eq. (20), then (12) and (21) as for the GM model."""
    W = crb_inverse_inertia(terms)
    return JumpMaps(normal_impulse_map(W, normal, restitution), terms.J_pinv @ W, W)


def reference_crb_jump(terms, normal, velocity, restitution) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``jump_kernels.crb_jump``: W_crb (20), iota = G v- (12), dq_jump = J+ W_crb iota (21)."""
    W = crb_inverse_inertia(terms)
    impulse = normal_impulse_map(W, normal, restitution) @ velocity
    return terms.J_pinv @ W @ impulse, impulse, W


def reference_crb_inverse_inertia_times(terms, normal) -> np.ndarray:
    """``CompositeRigidBodyJump.inverse_inertia_times`` in plain floats: n / m - r x (I_c^-1 (r x n))."""
    rx, ry, rz = (terms.contact_point - terms.com).tolist()
    nx, ny, nz = normal.tolist()
    ax, ay, az = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx  # r x n
    inverse, _ = symmetric_inverse3(terms.inertia_com)
    bx = inverse[0][0] * ax + inverse[0][1] * ay + inverse[0][2] * az
    by = inverse[1][0] * ax + inverse[1][1] * ay + inverse[1][2] * az
    bz = inverse[2][0] * ax + inverse[2][1] * ay + inverse[2][2] * az
    m = 1.0 / terms.mass
    return np.array([
        nx * m - (ry * bz - rz * by), ny * m - (rz * bx - rx * bz), nz * m - (rx * by - ry * bx)
    ])


def reference_rank_one_jump_matrices(model, terms, normal, restitution) -> JumpMatrices:
    """``GeneralizedMomentumJump.fixed_base_matrices`` (both normal-impulse models) in plain numpy:
    A = s (J^T (J J^T)^-1 W n)(J^T n)^T, P = s (J^T n)(J^T n)^T and G = s n n^T,
    s = -(1+c_r) / (n^T W n)."""
    Jt_normal = normal @ terms.J
    W_normal = model.inverse_inertia_times(terms, normal)
    s = -(1.0 + restitution) / float(normal @ W_normal)
    jump_direction = terms.J.T @ (terms.JJt_inv @ (s * W_normal))
    return JumpMatrices(
        jump_direction[:, None] * Jt_normal, (s * Jt_normal)[:, None] * Jt_normal, s * np.outer(normal, normal), None
    )


def reference_classical_jump_matrices(terms, restitution) -> JumpMatrices:
    """``classical_jump_matrices`` in plain numpy: G = -(1+c_r) (J M^-1 J^T)^-1 (5)-(6),
    A = M^-1 J^T G J and P = J^T G J."""
    MinvJt = terms.M_inv @ terms.J.T
    G = -(1.0 + restitution) * np.linalg.inv(terms.J @ MinvJt)
    return JumpMatrices(MinvJt @ G @ terms.J, terms.J.T @ G @ terms.J, G, None)
