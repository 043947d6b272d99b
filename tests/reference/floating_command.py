"""Plain-numpy statements of the compiled kernels of a floating base's command
(``controller.qp.floating_command``)."""

import numpy as np

from impactqp.controller.qp.command import DQ_MAX, Q_MAX, Q_MIN


def reference_velocity_command(dq, ddq, dt, limits, jump_matrix):
    """``floating_velocity_command``: (dq_cmd, the half step (dq + dq_cmd) dt / 2, the jump
    A dq_cmd, clipped)."""
    joints = len(dq) - limits.shape[1]
    dq_cmd = dq + ddq * dt
    clipped = bool(np.any(np.abs(dq_cmd[joints:]) > limits[DQ_MAX]))
    dq_cmd[joints:] = np.clip(dq_cmd[joints:], -limits[DQ_MAX], limits[DQ_MAX])
    return dq_cmd, 0.5 * dt * (dq + dq_cmd), jump_matrix @ dq_cmd, clipped


def reference_joint_positions_within(q, limits):
    """``joint_positions_within``, in a new array."""
    q = q.copy()
    joints = len(q) - limits.shape[1]
    q[joints:] = np.clip(q[joints:], limits[Q_MIN], limits[Q_MAX])
    return q
