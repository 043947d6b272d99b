"""Plain-numpy statements of the compiled kernels of a floating base's per-cycle fill
(``controller.model.floating_kernels``)."""

import numpy as np

from impactqp.controller.model.model_terms import ACCEPTED, MAX_STATE_ENTRY, NOT_FINITE
from impactqp.controller.model.floating_kernels import NOT_UNIT_QUATERNION


def reference_floating_state_status(q, v, base_nq, quaternion_tolerance):
    """``floating_state_status``'s status (without the copy)."""
    if not np.abs(q).sum() + np.abs(v).sum() <= (len(q) + len(v)) * MAX_STATE_ENTRY:
        return NOT_FINITE
    if abs(np.linalg.norm(q[3:base_nq]) - 1.0) > quaternion_tolerance:
        return NOT_UNIT_QUATERNION
    return ACCEPTED


def reference_floating_frames(Jw, joints, frames):
    """``floating_frames_into``: (J6, dJ6 v, p, R) stacked over the frames, in new arrays, from
    the joints' placements (R_i, t_i), twists (v_i, w_i) and accelerations (a_i, dw_i) in their
    own axes: p = R_i r + t_i, R = R_i R_l, J6 = [Jw_lin + Jw_ang x p; Jw_ang] on the support,
    dJ6 v = [R_i (a_i + dw_i x r + w_i x (v_i + w_i x r)); R_i dw_i]."""
    local, support = frames
    J6, drift, position, rotation = [], [], [], []
    for (R, t, v, w, a, dw), (R_l, r), columns in zip(joints, zip(local[:, :3], local[:, 3]), support.astype(bool)):
        p = R @ r + t
        J = np.zeros((6, Jw.shape[1]))
        J[:3, columns] = Jw[:3, columns] + np.cross(Jw[3:, columns].T, p).T
        J[3:, columns] = Jw[3:, columns]
        J6.append(J)
        drift.append(np.concatenate([R @ (a + np.cross(dw, r) + np.cross(w, v + np.cross(w, r))), R @ dw]))
        position.append(p)
        rotation.append(R @ R_l)
    return np.array(J6), np.array(drift), np.array(position), np.array(rotation)
