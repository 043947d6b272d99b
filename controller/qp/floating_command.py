"""The compiled kernels of a floating base's command (``ImpactAwareController``'s G1 step):
dq_cmd = dq + ddq dt with the joints' part within their velocity limits and its impact
prediction, the half step (dq + dq_cmd) dt / 2 that ``pin.integrate`` takes q along (q_cmd =
q (+) (dq + dq_cmd) dt / 2 on the configuration manifold: the free flyer's part is not a sum),
and the joints' part of q_cmd within their position limits. ``limits`` are the joints' stacked
``command.command_limits`` (one column per joint): the joints are the last columns of dq and the
last coordinates of q."""

from __future__ import annotations

from numba import njit

from .command import DQ_MAX, Q_MAX, Q_MIN
from .cycle_kernels import predicted_jump_rows


@njit(cache=True)
def floating_velocity_command(dq, ddq, dt, limits, jump_matrix, out):
    """Kernel: out[0] = dq_cmd = dq + ddq dt, each joint's rate clipped to +-dq_max (the base's
    twist is not), out[1] = (dq + dq_cmd) dt / 2, out[2] = the predicted jump A dq_cmd of the
    jump matrix A at the commanded velocity and out[3] = dq_cmd + A dq_cmd, the predicted
    post-impact velocity (``cycle_kernels.predicted_jump_rows``); True when a joint's
    rate was clipped."""
    clipped = False
    n = dq.shape[0]
    base = n - limits.shape[1]
    for i in range(n):
        v = dq[i] + ddq[i] * dt
        if i >= base:
            dq_max = limits[DQ_MAX, i - base]
            if v > dq_max:
                v, clipped = dq_max, True
            elif v < -dq_max:
                v, clipped = -dq_max, True
        out[0, i] = v
        out[1, i] = 0.5 * dt * (dq[i] + v)
    predicted_jump_rows(jump_matrix, out)
    return clipped


@njit(cache=True)
def joint_positions_within(q, limits):
    """Kernel: the joints' coordinates of q (its last ones) clipped into [q_min, q_max], in place."""
    base = q.shape[0] - limits.shape[1]
    for i in range(limits.shape[1]):
        q[base + i] = min(max(q[base + i], limits[Q_MIN, i]), limits[Q_MAX, i])
