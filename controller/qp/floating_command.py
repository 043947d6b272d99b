"""A floating base's command (``ImpactAwareController``'s G1 step) and its compiled kernels:
dq_cmd = dq + ddq dt with the joints' part within their velocity limits and its impact
prediction, the half step (dq + dq_cmd) dt / 2 that ``pin.integrate`` takes q along (q_cmd =
q (+) (dq + dq_cmd) dt / 2 on the configuration manifold: the free flyer's part is not a sum),
and the joints' part of q_cmd within their position limits. ``limits`` are the joints' stacked
``command.command_limits`` (one column per joint): the joints are the last columns of dq and the
last coordinates of q. The brake of a floating base's fallback (``held_brake``) keeps its held
contacts' rows.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.robot import RobotModel

from .command import DQ_MAX, Q_MAX, Q_MIN
from .cycle_kernels import COMMAND_ROWS, predicted_jump_rows
from .fallback import braking_command


def floating_command(model: pin.Model, terms: ModelTerms, ddq: np.ndarray, dt: float, limits: np.ndarray,
                     jump_matrix: np.ndarray) -> tuple:
    """(dq_cmd = dq + ddq dt (joints within their velocity limits), q_cmd = q (+) (dq + dq_cmd) dt / 2
    (``configuration_step``), the jump A dq_cmd, the post-impact velocity, whether dq_cmd was
    clipped) at the terms' state (``floating_velocity_command``; a fixed base:
    ``cycle_kernels.integrate_command``)."""
    command = np.empty((COMMAND_ROWS, terms.dq.shape[0]))
    clipped = floating_velocity_command(terms.dq, ddq, dt, limits, jump_matrix, command)
    return command[0], configuration_step(model, terms.q, command[1], limits), command[2], command[3], clipped


def configuration_step(model: pin.Model, q: np.ndarray, step: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """q (+) step (``pin.integrate``), the joints' coordinates within their limits."""
    q_cmd = pin.integrate(model, q, step)
    joint_positions_within(q_cmd, limits)
    return q_cmd


def held_brake(robot: RobotModel, terms: ModelTerms, previous_ddq: np.ndarray, dt: float, limits: np.ndarray) -> tuple:
    """(ddq, dq_cmd, q_cmd) of the joints' brake (``fallback.braking_command``, from the previous
    command's ``previous_ddq``) with a still base, projected onto the held contacts' rows by the
    least-norm change ddq = ddq_b - Jf^T (Jf Jf^T)^+ (Jf ddq_b + dJf dq) (a pseudo-inverse: a
    stretched leg makes Jf rank deficient). The base's twist of dq_cmd is then the one that keeps
    the held contacts still at the joints' clipped rates, Jf_base v_base = -Jf_joints dq_joints in
    the least-squares sense (Jf_base stacks each contact's adjoint, of full rank), so that a state
    the brake cannot follow (joints measured beyond their velocity limits, cycle after cycle)
    builds up no base velocity; ddq = (dq_cmd - dq) / dt. q_cmd = q (+) (dq + dq_cmd) dt / 2."""
    base, joints = slice(0, robot.base_nv), slice(robot.base_nv, None)
    ddq, dq_cmd = np.zeros(robot.nv), np.empty(robot.nv)
    braking_command(
        terms.q[robot.base_nq:], terms.dq[joints], previous_ddq[joints], dt, limits, ddq[joints], dq_cmd[joints],
        np.empty(robot.n_joints),
    )
    Jf = terms.held_jacobian
    if Jf.shape[0]:
        ddq -= Jf.T @ np.linalg.lstsq(Jf @ Jf.T, Jf @ ddq + terms.held_drift, rcond=None)[0]
    dq_cmd = terms.dq + ddq * dt
    np.clip(dq_cmd[joints], -robot.dq_max, robot.dq_max, out=dq_cmd[joints])
    if Jf.shape[0]:
        dq_cmd[base] = np.linalg.lstsq(Jf[:, base], -Jf[:, joints] @ dq_cmd[joints], rcond=None)[0]
    ddq = (dq_cmd - terms.dq) * (1.0 / dt)  # the acceleration commanded, clips and base twist included
    return ddq, dq_cmd, configuration_step(robot.model, terms.q, 0.5 * dt * (terms.dq + dq_cmd), limits)


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
