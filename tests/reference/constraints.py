"""Plain-numpy statements of the compiled constraint kernels (``constraints``): the rows each
class's ``compute_into`` must write, the relaxation of ``ControlCycle.recoverable``, the
inputs of the activation rule and an arm's per-fill jump matrices of an expected impact."""

import numpy as np

from impactqp.constraints import CaptureRegionLimit, FootWrenchLimit, HeldContactRows
from impactqp.constraints import (
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
)
from impactqp.controller.model.capture import GRAVITY
from impactqp.controller.model.jump import JumpMatrices

from .jump import reference_classical_jump_matrices, reference_rank_one_jump_matrices


def symmetric_rows_into(C, dq, limit, inv_h, active, lower, upper) -> None:
    """Bounds of the rows C ddq that keep |C (dq + h ddq)| <= limit: (+-limit - C dq) / h when the
    rows are ``active``, unbounded otherwise."""
    if not active:
        lower.fill(-np.inf)
        upper.fill(np.inf)
        return
    centre = inv_h * (C @ dq)
    scaled_limit = inv_h * limit
    np.subtract(-scaled_limit, centre, out=lower)
    np.subtract(scaled_limit, centre, out=upper)


def _position_rows(c: PositionLimit, terms, cycle, lower, upper) -> None:
    """The bounds of the actuated joints (the last entries; a floating base's unbounded)."""
    joints = c._limits.shape[1]
    lower[:-joints], upper[:-joints] = -np.inf, np.inf
    lower, upper = lower[-joints:], upper[-joints:]
    q, dq = terms.q[-joints:], terms.dq[-joints:]
    dt = cycle.dt
    if dt != c._dt:
        c._constants(dt)
    half_step, half_step_squared, twice_braking = c._braking_terms
    towards = c._sign * dq  # velocity towards each limit
    # d_e = max(sign (limit - q) - dt/2 sign dq - a dt^2/8, 0)
    distance = np.maximum(c._signed_limits - c._sign * (q + (0.5 * dt) * dq), 0.0)
    allowed = np.sqrt(half_step_squared + twice_braking * distance)
    allowed -= half_step + towards
    allowed *= 1.0 / dt
    np.negative(allowed[1], out=lower)
    upper[:] = allowed[0]


def reference_rows(constraint, terms, cycle, C, lower, upper) -> None:
    """The raw rows of ``constraint`` at ``terms`` in plain numpy (``compute_into`` itself for a
    class without a kernel)."""
    inv_h = 1.0 / cycle.horizon
    if isinstance(constraint, PositionLimit):
        _position_rows(constraint, terms, cycle, lower, upper)
    elif isinstance(constraint, VelocityLimit):  # the actuated joints, a floating base's unbounded
        joints = constraint.rows
        lower[:-joints], upper[:-joints] = -np.inf, np.inf
        np.subtract(-inv_h * constraint.dq_max, inv_h * terms.dq[-joints:], out=lower[-joints:])
        np.subtract(inv_h * constraint.dq_max, inv_h * terms.dq[-joints:], out=upper[-joints:])
    elif isinstance(constraint, TorqueLimit):
        inv = 1.0 / np.diagonal(terms.M)
        np.multiply(terms.M, inv[:, None], out=C)
        np.multiply(-constraint.tau_max - terms.h, inv, out=lower)
        np.multiply(constraint.tau_max - terms.h, inv, out=upper)
    elif isinstance(constraint, PostImpactVelocityLimit):
        impact = constraint.impact
        n, rows = C.shape[1], len(constraint.dq_max)  # dq+ = S (I + A) dq-, S the last rows (the actuated joints)
        jumps = [impact.matrices(terms).jump_matrix, *impact.edge_matrices(terms).jump]  # then each edge's A_i
        C[:] = np.vstack([(np.eye(n) + A)[n - rows:] for A in jumps])
        limit = np.tile(constraint.dq_max, len(jumps))
        symmetric_rows_into(C, terms.dq, limit, inv_h, impact.is_active(terms), lower, upper)
    elif isinstance(constraint, ImpulsiveTorqueLimit):
        impact = constraint.impact
        torques = [impact.matrices(terms).torque_matrix, *impact.edge_matrices(terms).torque]  # then each edge's P_i
        C[:] = np.vstack([P * constraint.row_scale[:, None] for P in torques])  # rows s_i P_i
        # s_i tau_max_i delta_t = dq_max_i
        scaled_limit = np.tile(constraint.row_scale * constraint.impulse_limit, len(torques))
        symmetric_rows_into(C, terms.dq, scaled_limit, inv_h, impact.is_active(terms), lower, upper)
    elif type(constraint) is HeldContactRows:
        C[:] = terms.held_jacobian
        lower[:] = upper[:] = -terms.held_drift
    elif type(constraint) in (CaptureRegionLimit, FootWrenchLimit):
        lower.fill(-np.inf)
        upper.fill(np.inf)
        C[:] = 0.0
        if constraint.impact.is_active(terms):
            rows = _capture_rows if type(constraint) is CaptureRegionLimit else _foot_wrench_rows
            C[:], upper[:] = rows(constraint, terms, inv_h)
    else:
        constraint.compute_into(terms, cycle, C, lower, upper)


def _capture_rows(c: CaptureRegionLimit, terms, inv_h: float) -> tuple[np.ndarray, np.ndarray]:
    """nu K_xy dv <= (omega nu . (a - c) - nu K_xy v) / h, K = Jcom + C G J."""
    maps = c.impact.matrices(terms)
    K = terms.Jcom + maps.com_map @ maps.impulse_map @ terms.J
    rows = c._normals @ K[:2]
    omega = np.sqrt(GRAVITY / (terms.com[2] - c.ground_height))
    return rows, (omega * (c._offsets - c._normals @ terms.com[:2]) - rows @ terms.dq) * inv_h


def _foot_wrench_rows(c: FootWrenchLimit, terms, inv_h: float) -> tuple[np.ndarray, np.ndarray]:
    """Per foot k, for each row e of its axes (the slip row at this state's peak wrench, then the
    sole's rows), with the world row E = diag(R_k, R_k) e: E . L_k dv / m <= (-T E . w_k / m - E . L_k v / m) / h,
    L = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T G J and w the standing map of the weight m g at c."""
    Jf, M_inv, J, m = terms.held_jacobian, terms.M_inv, terms.J, terms.mass
    L = -np.linalg.solve(Jf @ M_inv @ Jf.T, Jf @ M_inv @ J.T) @ c.impact.matrices(terms).impulse_map @ J
    weight = m * GRAVITY
    w = c.duration * c._standing @ np.array([0.0, 0.0, weight, terms.com[1] * weight, -terms.com[0] * weight, 0.0])
    peak = w + L @ terms.dq
    rows, upper = [], []
    for k, R in enumerate(c._rotations):
        block = slice(6 * k, 6 * k + 6)
        tangential = (R.T @ peak[block][:3])[:2]
        norm = np.linalg.norm(tangential)
        u = tangential / norm if norm > 0.0 else np.array([1.0, 0.0])
        for e in [np.array([u[0], u[1], -c._friction[k], 0.0, 0.0, 0.0]), *c._soles[k]]:
            world = np.concatenate([R @ e[:3], R @ e[3:]])
            row = world @ L[block] / m
            rows.append(row)
            upper.append((-(world @ w[block]) / m - row @ terms.dq) * inv_h)
    return np.array(rows), np.array(upper)


def reference_recoverable(cycle, C, lower, upper):
    """``ControlCycle.recoverable`` in plain numpy: lower <= c + s and upper >= c - s, with
    c = C (lo + hi) / 2 and s = |C| (hi - lo) / 2 over the cycle's box [lo, hi]."""
    lo, hi = cycle.acceleration_lower, cycle.acceleration_upper
    centre = C @ (0.5 * (lo + hi))
    spread = np.abs(C) @ (0.5 * (hi - lo))
    np.minimum(lower, centre + spread, out=lower)
    np.maximum(upper, centre - spread, out=upper)
    return lower, upper


def reference_normal_motion(terms, normal) -> tuple[float, float]:
    """The inputs of the activation rule, n.(J dq) and n.p, in plain numpy."""
    return float((normal @ terms.J) @ terms.dq), float(normal @ terms.contact_point)


def reference_fixed_base_cycle_update(model, terms, normal, restitution) -> tuple[JumpMatrices, tuple[float, float]]:
    """``crb_cycle_update``, ``gm_cycle_update`` and ``classical_cycle_update`` (a fixed base's
    crb, gm or classical fill of an expected impact) in plain numpy: A, P and G, then n.(J dq)
    and n.p."""
    if model.name == "classical":
        matrices = reference_classical_jump_matrices(terms, restitution)
    else:
        matrices = reference_rank_one_jump_matrices(model, terms, normal, restitution)
    return matrices, reference_normal_motion(terms, normal)
