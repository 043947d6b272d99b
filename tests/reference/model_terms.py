"""Plain-numpy statements of the compiled kernels of an arm's model terms
(``controller.model.model_terms``)."""

import numpy as np

from impactqp.controller.model.model_terms import ACCEPTED, MAX_STATE_ENTRY, NEAR_SINGULAR, NOT_FINITE, OUTSIDE_LIMITS


def reference_arm_cycle_terms(world, state, checks):
    """``arm_cycle_terms``: (status, J6, (J J^T)^-1, p, dJ6 dq, dq, R, q) from Pinocchio's
    world-frame joint Jacobians Jw and their rate dJw at the contact point p of rotation R (the
    support columns only): J6 = [Jw_lin + Jw_ang x p; Jw_ang], dJ6 dq = [a_O + dw x p +
    w x (v_O + w x p); dw], the state and R passed through (``arm_state_views``' order)."""
    Jw, dJw, p, R, support = world
    q, dq = state
    q_limits, check_limits, singular_ratio_squared = checks
    refused = (None,) * 7
    if not np.abs(q).sum() + np.abs(dq).sum() <= (len(q) + len(dq)) * MAX_STATE_ENTRY:
        return (NOT_FINITE, *refused)
    J6 = np.zeros((6, len(dq)))
    J6[:3, support] = Jw[:3, support] + np.cross(Jw[3:, support].T, p).T
    J6[3:, support] = Jw[3:, support]
    v_O, w = np.split(Jw[:, support] @ dq[support], 2)
    a_O, dw = np.split(dJw[:, support] @ dq[support], 2)
    drift = np.concatenate([a_O + np.cross(dw, p) + np.cross(w, v_O + np.cross(w, p)), dw])
    S = J6[:3] @ J6[:3].T
    if not np.linalg.det(S) >= singular_ratio_squared * np.trace(S) ** 3:
        return (NEAR_SINGULAR, *refused)
    if check_limits and (np.any(q < q_limits[0]) or np.any(q > q_limits[1])):
        return (OUTSIDE_LIMITS, *refused)
    return ACCEPTED, J6, np.linalg.inv(S), p, drift, dq, R, q
