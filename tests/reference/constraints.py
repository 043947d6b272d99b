"""Plain-numpy statements of the compiled constraint kernels (``constraints``): the rows each
class's ``compute_into`` must write, the relaxation of ``ControlCycle.recoverable``, the
inputs of the activation rule and an arm's per-fill jump matrices of an expected impact."""

import numpy as np

from impactqp.constraints import (
    ImpulsiveTorqueLimit,
    PositionLimit,
    PostImpactVelocityLimit,
    TorqueLimit,
    VelocityLimit,
)
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
    dt = cycle.dt
    if dt != c._dt:
        c._constants(dt)
    half_step, half_step_squared, twice_braking = c._braking_terms
    towards = c._sign * terms.dq  # velocity towards each limit
    # d_e = max(sign (limit - q) - dt/2 sign dq - a dt^2/8, 0)
    distance = np.maximum(c._signed_limits - c._sign * (terms.q + (0.5 * dt) * terms.dq), 0.0)
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
    elif isinstance(constraint, VelocityLimit):
        np.subtract(-inv_h * constraint.dq_max, inv_h * terms.dq, out=lower)
        np.subtract(inv_h * constraint.dq_max, inv_h * terms.dq, out=upper)
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
    else:
        constraint.compute_into(terms, cycle, C, lower, upper)


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
