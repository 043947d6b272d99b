"""Plain-numpy statements of the compiled kernels of an arm's model terms
(``controller.model.model_terms``)."""

import numpy as np

from impactqp.controller.model.model_terms import ACCEPTED, MAX_STATE_ENTRY, NEAR_SINGULAR, NOT_FINITE, OUTSIDE_LIMITS


def reference_arm_cycle_terms(world, state, checks):
    """``arm_cycle_terms``: (status, J6, dJ6 dq, (J J^T)^-1, contact terms) from Pinocchio's
    world-frame joint Jacobians Jw and their rate dJw at the contact point p (the support columns
    only): J6 = [Jw_lin + Jw_ang x p; Jw_ang], dJ6 dq = [a_O + dw x p + w x (v_O + w x p); dw],
    and the contact terms [J6, (J J^T)^-1, p] flattened row-major, one after the other."""
    Jw, dJw, p, support = world
    q, dq = state
    q_limits, check_limits, singular_ratio_squared = checks
    if not np.abs(q).sum() + np.abs(dq).sum() <= (len(q) + len(dq)) * MAX_STATE_ENTRY:
        return NOT_FINITE, None, None, None, None
    J6 = np.zeros((6, len(dq)))
    J6[:3, support] = Jw[:3, support] + np.cross(Jw[3:, support].T, p).T
    J6[3:, support] = Jw[3:, support]
    v_O, w = np.split(Jw[:, support] @ dq[support], 2)
    a_O, dw = np.split(dJw[:, support] @ dq[support], 2)
    drift = np.concatenate([a_O + np.cross(dw, p) + np.cross(w, v_O + np.cross(w, p)), dw])
    S = J6[:3] @ J6[:3].T
    if not np.linalg.det(S) >= singular_ratio_squared * np.trace(S) ** 3:
        return NEAR_SINGULAR, None, None, None, None
    if check_limits and (np.any(q < q_limits[0]) or np.any(q > q_limits[1])):
        return OUTSIDE_LIMITS, None, None, None, None
    JJt_inv = np.linalg.inv(S)
    return ACCEPTED, J6, drift, JJt_inv, np.concatenate([J6.ravel(), JJt_inv.ravel(), p])
