"""The per-cycle kernels of a fixed base's expected impact (``impact_model.ExpectedImpact``):
the crb, gm and classical jump matrices A, P and G (docs/qp-constraints.md: A = dq+/dq- - I,
P the impulsive torque map, G the impulse map; eqs. (12), (20), (21)) written into one
preallocated buffer out = [A, P, G] from the cycle's flat arrays (``ModelTerms.contact_terms``),
and the contact's normal motion that the activation rule reads; the rule itself
(``activation``) and a compiled plan's update of its impacts (``stacked_updates``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.classical_matrices import classical_jump_matrices
from impactqp.controller.model.friction_pyramid import edge_matrices_into
from impactqp.controller.model.jump_kernels import (
    cholesky_solve_in_place,
    crb_inverse_inertia_times,
    rank_one_jump_matrices,
    welded_inverse_inertia,
)
from impactqp.controller.model.model_terms import contact_views


@njit(cache=True)
def normal_motion(J, normal, contact_point, dq):
    """Kernel: the normal contact speed n.(J dq) = (J^T n).dq and the normal position n.p, the
    inputs of the activation rule (plain loops: no BLAS call at this size)."""
    normal_speed = 0.0
    for j in range(J.shape[1]):
        normal_speed += (normal[0] * J[0, j] + normal[1] * J[1, j] + normal[2] * J[2, j]) * dq[j]
    normal_position = normal[0] * contact_point[0] + normal[1] * contact_point[1] + normal[2] * contact_point[2]
    return normal_speed, normal_position


@njit(cache=True)
def fixed_base_matrix_views(out, n):
    """The views (A (n x n), P (n x n), G (3 x 3)) of ``out`` = [A, P, G] flat, row-major
    (2 n^2 + 9 values): the buffer of a fixed base's fill (``ExpectedImpact._fill_fixed_base``),
    for its kernels and for Python alike."""
    return out[:n * n].reshape(n, n), out[n * n:2 * n * n].reshape(n, n), out[2 * n * n:2 * n * n + 9].reshape(3, 3)


@njit(cache=True)
def rank_one_cycle_update(W_normal, contact, dq, impact, out):
    """Kernel: the rank-one part of a fixed base's crb and gm fills (``crb_cycle_update``,
    ``gm_cycle_update``): from W n, A = s (J+ W n)(J^T n)^T, P = s (J^T n)(J^T n)^T and G = s n n^T, s = -(1+c_r) / (n^T W n)
    (eq. (12), ``rank_one_jump_matrices``), into out = [A, P, G] (``fixed_base_matrix_views``),
    with J, (J J^T)^-1 and p from ``contact`` (``model_terms.contact_views``) and
    impact = [n, c_r]; returns n.(J dq) and n.p (``normal_motion``)."""
    nv = dq.shape[0]
    J6, JJt_inv, contact_point = contact_views(contact, nv)
    J, normal = J6[:3], impact[:3]
    jump_matrix, torque_matrix, impulse_map = fixed_base_matrix_views(out, nv)
    rank_one_jump_matrices(J, JJt_inv, W_normal, normal, impact[3], jump_matrix, torque_matrix, impulse_map)
    return normal_motion(J, normal, contact_point, dq)


@njit(cache=True)
def crb_cycle_update(contact, com, inertia_com, mass, dq, impact, out):
    """Kernel: ``rank_one_cycle_update`` with W = W_crb, eq. (20), its W_crb n from the contact
    point p (in ``contact``), the centre of mass, the inertia about it and the mass
    (``crb_inverse_inertia_times``)."""
    contact_point = contact_views(contact, dq.shape[0])[2]
    W_normal = crb_inverse_inertia_times(contact_point, com, inertia_com, mass, impact[:3])
    return rank_one_cycle_update(W_normal, contact, dq, impact, out)


@njit(cache=True)
def gm_cycle_update(M_inv, contact, dq, impact, out):
    """Kernel: ``rank_one_cycle_update`` with W = W_gm = J M^-1 J^T, eq. (22), its
    W_gm n = J (M^-1 (J^T n)) in plain loops (``GeneralizedMomentumJump.inverse_inertia_times``;
    BLAS would cost more than the products at this size)."""
    nv = dq.shape[0]
    J6 = contact_views(contact, nv)[0]
    n0, n1, n2 = impact[0], impact[1], impact[2]
    Jt_normal = np.empty(nv)
    for k in range(nv):
        Jt_normal[k] = J6[0, k] * n0 + J6[1, k] * n1 + J6[2, k] * n2
    W_normal = np.zeros(3)
    for i in range(nv):
        y = 0.0  # (M^-1 J^T n)_i
        for k in range(nv):
            y += M_inv[i, k] * Jt_normal[k]
        W_normal[0] += J6[0, i] * y
        W_normal[1] += J6[1, i] * y
        W_normal[2] += J6[2, i] * y
    return rank_one_cycle_update(W_normal, contact, dq, impact, out)


@njit(cache=True)
def classical_cycle_update(M_inv, contact, dq, impact, out):
    """Kernel of a fixed base's classical fill (``ExpectedImpact._fill_fixed_base``): A, P and
    G of eqs. (5)-(6) (``classical_jump_matrices``) into out = [A, P, G], with J and p from
    ``contact`` and impact = [n, c_r] (as ``rank_one_cycle_update``); returns n.(J dq) and n.p
    (``normal_motion``)."""
    nv = dq.shape[0]
    J6, _, contact_point = contact_views(contact, nv)
    J, normal = J6[:3], impact[:3]
    jump_matrix, torque_matrix, impulse_map = fixed_base_matrix_views(out, nv)
    classical_jump_matrices(M_inv, J, impact[3], jump_matrix, torque_matrix, impulse_map)
    return normal_motion(J, normal, contact_point, dq)


RULE_VALUES = 10
"""An impact's rule values (``ExpectedImpact.rule_values``): n (3), c_r, always_active (1 or 0),
release_speed, lookahead_distance, lookahead_time, n.s (the surface's offset along n) and its
model (``CRB``, ``GM`` or ``CLASSICAL``)."""
ALWAYS_ACTIVE, RELEASE_SPEED, LOOKAHEAD_DISTANCE, LOOKAHEAD_TIME, SURFACE_OFFSET, MODEL = range(4, 10)
CRB, GM, CLASSICAL = range(3)


@njit(cache=True)
def activation(rule, normal_speed, normal_position):
    """Kernel: the activation rule (``impact_model``'s module docstring) of the rule values ``rule``
    at the contact's n.(J dq) and n.p: always, or the contact not leaving (n.v <= release_speed)
    and the surface near (n.p - n.s <= max(lookahead_distance, -n.v lookahead_time))."""
    if rule[ALWAYS_ACTIVE] != 0.0:
        return True
    if normal_speed > rule[RELEASE_SPEED]:
        return False
    return normal_position - rule[SURFACE_OFFSET] <= max(rule[LOOKAHEAD_DISTANCE], -normal_speed * rule[LOOKAHEAD_TIME])


@njit(cache=True)
def stacked_updates(contact, dq, locked, M, rules, impacts):
    """Kernel: each fixed-base impact i of a compiled plan (``cycle_plan``) updated in its row of
    ``impacts`` = [A, P, G (in 3 n^2 values), its edges' A_i and P_i (2 x edges x n^2), its
    activation], as the impact's own fills do: A, P, G by its model's kernel (``crb_cycle_update``,
    ``gm_cycle_update`` or ``classical_cycle_update``), the edges' maps by ``edge_matrices_into``
    with its model's W (W_crb, ``welded_inverse_inertia``; else W_gm = J M^-1 J^T), and the
    activation (1 or 0); from the arm's ``contact`` terms, dq, ``locked`` = [centre of mass,
    inertia about it (row-major), mass] of the locked robot, M (its inverse by Cholesky, once,
    when a gm or classical impact needs it; NaN when M is not positive definite, which the
    solution's check then refuses) and the impacts' ``ExpectedImpact.plan_values`` (rules[i]: its
    rule values, then its edges' directions)."""
    n = dq.shape[0]
    square = n * n
    edges = ((impacts.shape[1] - 1) // square - 3) // 2
    com, inertia, mass = locked[:3], locked[3:12].reshape((3, 3)), locked[12]
    J6, JJt_inv, contact_point = contact_views(contact, n)
    J = J6[:3]
    no_matrix = np.empty((0, 0))  # M^-1's place when no model reads it
    M_inv = no_matrix
    for i in range(rules.shape[0]):
        rule, row = rules[i], impacts[i]
        model, maps = int(rule[MODEL]), row[:2 * square + 9]
        if model != CRB and M_inv.shape[0] == 0:
            M_inv = symmetric_positive_inverse(M)
        if model == CRB:
            normal_speed, normal_position = crb_cycle_update(contact, com, inertia, mass, dq, rule[:4], maps)
        elif model == GM:
            normal_speed, normal_position = gm_cycle_update(M_inv, contact, dq, rule[:4], maps)
        else:
            normal_speed, normal_position = classical_cycle_update(M_inv, contact, dq, rule[:4], maps)
        if edges:
            W = welded_inverse_inertia(contact_point, com, inertia, mass) if model == CRB else gm_contact_inverse_inertia(M_inv, J)
            directions = rule[RULE_VALUES:RULE_VALUES + 3 * edges].reshape((edges, 3))
            edge_maps = row[3 * square:3 * square + 2 * edges * square].reshape((2, edges, n, n))
            edge_matrices_into(J, JJt_inv, M_inv if model == CLASSICAL else no_matrix, W, directions, rule[:3], rule[3],
                               edge_maps)
        row[row.shape[0] - 1] = 1.0 if activation(rule, normal_speed, normal_position) else 0.0


@njit(cache=True)
def symmetric_positive_inverse(S):
    """Kernel: S^-1 of a symmetric positive definite S by its Cholesky factor
    (``cholesky_solve_in_place`` on the identity), in a new array; NaN when S is not positive
    definite."""
    n = S.shape[0]
    factor, inverse = S.copy(), np.eye(n)
    if not cholesky_solve_in_place(factor, inverse):
        inverse[:, :] = np.nan
    return inverse


@njit(cache=True)
def gm_contact_inverse_inertia(M_inv, J):
    """Kernel: W_gm = J M^-1 J^T (22) at the contact, symmetrized (``jump.gm_inverse_inertia``'s
    statement for a fixed base), in plain loops."""
    n = J.shape[1]
    W = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            total = 0.0
            for k in range(n):
                y = 0.0  # (M^-1 J^T)_kb
                for j in range(n):
                    y += M_inv[k, j] * J[b, j]
                total += J[a, k] * y
            W[a, b] = total
    for a in range(3):
        for b in range(a):
            W[a, b] = W[b, a] = 0.5 * (W[a, b] + W[b, a])
    return W
