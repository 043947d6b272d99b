"""The compiled kernels of a floating base's per-cycle fill (``term_fills.ModelTermFills``): the
state's check, and the frames' world-aligned Jacobians, drifts and placements written into the
buffer's arrays from Pinocchio's own arrays (no new array per frame).

After ``forwardKinematics(q, v, 0)`` and ``computeJointJacobians``, Pinocchio holds for each
joint i its world placement (R_i, t_i) (``data.oMi[i]``), its twist (v_i, w_i) and its
acceleration at ddq = 0 (a_i, dw_i), both at the joint's origin in its own axes (``data.v[i]``,
``data.a[i]``), and the world-frame joint Jacobians Jw (``data.J``: spatial velocities at the
world origin, linear then angular). A frame fixed on joint i at (R_l, r) in the joint's axes is
at p = R_i r + t_i, rotated by R = R_i R_l. Its point moves at v_p = v_O + w x p, so on the
columns of the velocities that move joint i its world-aligned Jacobian is
J6 = [Jw_lin + Jw_ang x p; Jw_ang] (zeros elsewhere), and its classical acceleration at
ddq = 0 (the drift dJ6 v) is [R_i (a_i + dw_i x r + w_i x (v_i + w_i x r)); R_i dw_i] (the
spatial acceleration moved to the point, plus w x v_p).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .model_terms import ACCEPTED, MAX_STATE_ENTRY, NOT_FINITE

QUATERNION_TOLERANCE = 1e-3
"""Largest | |quaternion| - 1 | of a floating base's orientation in a state (typed to a few digits)."""
NOT_UNIT_QUATERNION = 4
"""The status of a state whose base quaternion is not a unit one (``floating_state_status``)."""


@njit(cache=True)
def floating_state_status(q, v, base_nq, quaternion_tolerance, q_out, v_out):
    """Kernel of a floating base's state check: NOT_FINITE when sum |q_i| + sum |v_i| exceeds
    MAX_STATE_ENTRY (nq + nv) (a NaN, an infinity or a huge entry: ``check_state``'s test),
    else NOT_UNIT_QUATERNION when | |q[3:base_nq]| - 1 | exceeds the tolerance, else ACCEPTED
    with q and v copied into ``q_out`` and ``v_out`` (a refused state writes nothing)."""
    if not absolute_sum(q) + absolute_sum(v) <= (q.shape[0] + v.shape[0]) * MAX_STATE_ENTRY:
        return NOT_FINITE
    squared = 0.0
    for j in range(3, base_nq):
        squared += q[j] * q[j]
    if abs(np.sqrt(squared) - 1.0) > quaternion_tolerance:
        return NOT_UNIT_QUATERNION
    q_out[:] = q
    v_out[:] = v
    return ACCEPTED


@njit(cache=True)
def absolute_sum(values):
    """Kernel: sum |values_i| (NaN when one is NaN)."""
    total = 0.0
    for x in values:
        total += abs(x)
    return total


@njit(cache=True)
def floating_frames_into(Jw, joints, frames, out):
    """Kernel: each frame's world-aligned Jacobian, drift, position and rotation (module
    docstring) into ``out`` = (J6 (F x 6 x nv), dJ6 v (F x 6), p (F x 3), R (F x 3 x 3)).

    ``joints`` holds, for each frame, its joint's (R_i, t_i, v_i, w_i, a_i, dw_i) (views of
    Pinocchio's data); ``frames`` = (local, support): ``local[f]`` the frame's (R_l; r^T)
    (4 x 3) in its joint's axes, ``support[f, k]`` 1 when velocity k moves that joint."""
    local, support = frames
    J6, drift, position, rotation = out
    nv = Jw.shape[1]
    for f in range(len(joints)):
        R, t, v, w, a, dw = joints[f]
        rx, ry, rz = local[f, 3, 0], local[f, 3, 1], local[f, 3, 2]
        for i in range(3):
            position[f, i] = R[i, 0] * rx + R[i, 1] * ry + R[i, 2] * rz + t[i]
            for j in range(3):
                rotation[f, i, j] = R[i, 0] * local[f, 0, j] + R[i, 1] * local[f, 1, j] + R[i, 2] * local[f, 2, j]
        px, py, pz = position[f, 0], position[f, 1], position[f, 2]
        for k in range(nv):
            if support[f, k]:
                J6[f, 0, k] = Jw[0, k] + Jw[4, k] * pz - Jw[5, k] * py
                J6[f, 1, k] = Jw[1, k] + Jw[5, k] * px - Jw[3, k] * pz
                J6[f, 2, k] = Jw[2, k] + Jw[3, k] * py - Jw[4, k] * px
                J6[f, 3, k], J6[f, 4, k], J6[f, 5, k] = Jw[3, k], Jw[4, k], Jw[5, k]
            else:
                for i in range(6):
                    J6[f, i, k] = 0.0
        # the point's velocity and classical acceleration in the joint's axes
        ux = v[0] + w[1] * rz - w[2] * ry
        uy = v[1] + w[2] * rx - w[0] * rz
        uz = v[2] + w[0] * ry - w[1] * rx
        cx = a[0] + dw[1] * rz - dw[2] * ry + w[1] * uz - w[2] * uy
        cy = a[1] + dw[2] * rx - dw[0] * rz + w[2] * ux - w[0] * uz
        cz = a[2] + dw[0] * ry - dw[1] * rx + w[0] * uy - w[1] * ux
        for i in range(3):
            drift[f, i] = R[i, 0] * cx + R[i, 1] * cy + R[i, 2] * cz
            drift[f, 3 + i] = R[i, 0] * dw[0] + R[i, 1] * dw[1] + R[i, 2] * dw[2]


def floating_frame_arrays(count: int, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The output arrays of ``floating_frames_into`` for ``count`` frames: J6 (count x 6 x nv),
    dJ6 v (count x 6), p (count x 3), R (count x 3 x 3)."""
    return np.empty((count, 6, nv)), np.empty((count, 6)), np.empty((count, 3)), np.empty((count, 3, 3))
