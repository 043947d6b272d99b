"""Contact posture by inverse kinematics: the tool tip on a surface point, the tool axis along -n.

The task has five dimensions: the tip position p(q) = p* (3) and the tool axis (hand z axis) z(q)
= -n (2; the spin about the axis is free). With the world-aligned frame Jacobian J6 = [Jv; Jw],
the errors and their rates are

  e_p = p* - p,          de_p/dt = -Jv dq
  e_z = z x (-n),        the rotation that turns z onto -n, of norm sin(angle); the angular
                          velocity that reduces it is w = e_z, reached by P Jw dq with
                          P = I - z z^T (the spin w.z does not move the axis).

Each damped least-squares step solves dq = A^T (A A^T + lambda^2 I)^-1 e with A = [Jv; P Jw]
and e = [e_p; e_z], limited to ``MAX_STEP`` rad per joint and clipped to the joint limits. The
seed posture is the start; the solution is the posture of the nearest local minimum, which is
why a sweep documents its seed (docs/sweep.md).

:func:`contact_postures` runs the same iteration for N targets (every target from the same seed,
each one stopped at its own convergence) in a compiled kernel, with the forward kinematics of
``controller.model.batch.BatchKinematics`` written out and the 6x6 system solved by Cholesky;
:func:`reference_contact_postures` is its plain-numpy reference, one vectorised iteration for all
unsolved targets at once on ``BatchKinematics.contact_frames``. Both reach the postures of
:func:`contact_posture` up to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numba import njit

from .batch import BatchKinematics
from .robot import PandaModel

POSITION_TOLERANCE = 1e-6
"""Largest tip position error (m) of a reached posture."""

AXIS_TOLERANCE = 1e-5
"""Largest |z x (-n)| (sin of the axis angle error) of a reached posture."""

DAMPING = 1e-3
MAX_STEP = 0.2
MAX_ITERATIONS = 200


@dataclass(frozen=True)
class ContactPosture:
    """The result of :func:`contact_posture`: the last iterate and whether it reaches the target."""

    q: np.ndarray
    reachable: bool
    position_error: float  # m
    axis_error: float  # sin of the angle between the tool axis and -n


def contact_posture(
    robot: PandaModel,
    point,
    normal,
    seed,
    max_iterations: int = MAX_ITERATIONS,
) -> ContactPosture:
    """Joint posture within the limits with the contact tip at ``point`` and hand z along -``normal``.

    ``normal`` must be a unit vector (see ``validation.unit_normal``). The result is reachable when
    the position error is below ``POSITION_TOLERANCE`` and the axis error below ``AXIS_TOLERANCE``.
    """
    target = np.asarray(point, dtype=float)
    axis_target = -np.asarray(normal, dtype=float)
    q = np.clip(np.asarray(seed, dtype=float), robot.q_min, robot.q_max)
    model, data, fid = robot.model, robot.data, robot.contact_frame_id
    A = np.empty((6, q.size))
    e = np.empty(6)
    damping = DAMPING**2 * np.eye(6)
    position_error = axis_error = np.inf
    for iteration in range(max_iterations + 1):
        J6 = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        placement = data.oMf[fid]
        z = placement.rotation[:, 2]
        e[:3] = target - placement.translation
        e[3:] = np.cross(z, axis_target)
        position_error = float(np.linalg.norm(e[:3]))
        axis_error = float(np.linalg.norm(e[3:]))
        aligned = float(z @ axis_target) > 0.0
        if position_error < POSITION_TOLERANCE and axis_error < AXIS_TOLERANCE and aligned:
            return ContactPosture(q, True, position_error, axis_error)
        if iteration == max_iterations:
            break
        if not aligned:
            # Pointing away: the cross product vanishes at 180 degrees; turn about any normal axis.
            e[3:] = np.cross(z, axis_target + 0.5 * np.cross(z, np.roll(z, 1)))
        A[:3] = J6[:3]
        A[3:] = J6[3:] - np.outer(z, z @ J6[3:])
        step = A.T @ np.linalg.solve(A @ A.T + damping, e)
        q = np.clip(q + np.clip(step, -MAX_STEP, MAX_STEP), robot.q_min, robot.q_max)
    return ContactPosture(q, False, position_error, axis_error)


@dataclass(frozen=True)
class ContactPostures:
    """The result of :func:`contact_postures`: one row per target, as in :class:`ContactPosture`."""

    q: np.ndarray  # (N, 7)
    reachable: np.ndarray  # (N,) bool
    position_error: np.ndarray  # (N,) m
    axis_error: np.ndarray  # (N,)


def _start(robot, points, normals, seed):
    """The targets (N, 3), the tool-axis targets -n (N, 3), the seeds (N, 7) clipped into the
    limits, and the result arrays (not reachable, infinite errors) of a batch of targets."""
    targets = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    axis_targets = -np.ascontiguousarray(normals, dtype=float).reshape(-1, 3)
    n_targets = targets.shape[0]
    Q = np.tile(np.clip(np.asarray(seed, dtype=float), robot.q_min, robot.q_max), (n_targets, 1))
    return (
        targets, axis_targets, Q, np.zeros(n_targets, dtype=bool), np.full(n_targets, np.inf), np.full(n_targets, np.inf)
    )


def contact_postures(
    kinematics: BatchKinematics,
    points,
    normals,
    seed,
    max_iterations: int = MAX_ITERATIONS,
) -> ContactPostures:
    """:func:`contact_posture` for N targets (``points`` and unit ``normals``, (N, 3)), compiled."""
    robot = kinematics.robot
    targets, axis_targets, Q, reachable, position_error, axis_error = _start(robot, points, normals, seed)
    contact_postures_kernel(
        Q, targets, axis_targets, kinematics.R_joint, kinematics.p_joint, kinematics.p_contact,
        np.ascontiguousarray(kinematics.R_contact[:, 2]), robot.q_min, robot.q_max, max_iterations,
        DAMPING**2, MAX_STEP, POSITION_TOLERANCE, AXIS_TOLERANCE, reachable, position_error, axis_error,
    )
    return ContactPostures(Q, reachable, position_error, axis_error)


def reference_contact_postures(
    kinematics: BatchKinematics,
    points,
    normals,
    seed,
    max_iterations: int = MAX_ITERATIONS,
) -> ContactPostures:
    """:func:`contact_postures` in plain numpy (the reference of its kernel).

    Each iteration evaluates the frames of the targets still unsolved, tests them with the same
    tolerances and takes the same damped least-squares step (batched 6x6 solves).
    """
    robot = kinematics.robot
    targets, axis_targets, Q, reachable, position_error, axis_error = _start(robot, points, normals, seed)
    active = np.arange(targets.shape[0])
    damping = DAMPING**2 * np.eye(6)
    for iteration in range(max_iterations + 1):
        if active.size == 0:
            break
        q = Q[active]
        p, z, J6 = kinematics.contact_frames(q)
        axis_target = axis_targets[active]
        e = np.empty((active.size, 6))
        e[:, :3] = targets[active] - p
        e[:, 3:] = np.cross(z, axis_target)
        position_error[active] = np.linalg.norm(e[:, :3], axis=1)
        axis_error[active] = np.linalg.norm(e[:, 3:], axis=1)
        aligned = np.einsum("na,na->n", z, axis_target) > 0.0
        solved = (position_error[active] < POSITION_TOLERANCE) & (axis_error[active] < AXIS_TOLERANCE) & aligned
        reachable[active[solved]] = True
        if iteration == max_iterations:
            break
        keep = ~solved
        active, q, z, J6, e, aligned, axis_target = (
            active[keep], q[keep], z[keep], J6[keep], e[keep], aligned[keep], axis_target[keep]
        )
        away = ~aligned
        if np.any(away):
            # Pointing away: the cross product vanishes at 180 degrees; turn about any normal axis.
            za = z[away]
            e[away, 3:] = np.cross(za, axis_target[away] + 0.5 * np.cross(za, np.roll(za, 1, axis=1)))
        A = J6.copy()
        A[:, 3:] -= z[:, :, None] * np.einsum("na,nak->nk", z, J6[:, 3:])[:, None, :]
        step = np.einsum("nak,na->nk", A, np.linalg.solve(A @ np.swapaxes(A, 1, 2) + damping, e[:, :, None])[..., 0])
        Q[active] = np.clip(q + np.clip(step, -MAX_STEP, MAX_STEP), robot.q_min, robot.q_max)
    return ContactPostures(Q, reachable, position_error, axis_error)


@njit(cache=True)
def contact_postures_kernel(
    Q, targets, axis_targets, R_joint, p_joint, p_contact, z_contact, q_min, q_max,
    max_iterations, damping_squared, max_step, position_tolerance, axis_tolerance,
    reachable, position_error, axis_error,
):
    """Kernel of :func:`contact_postures`: the iteration of :func:`contact_posture` for each row
    of ``Q`` (the seeds, updated in place to the last iterates) with the forward kinematics of
    ``BatchKinematics`` written out, and (A A^T + lambda^2 I) x = e solved by Cholesky."""
    n_q = Q.shape[1]
    R = np.empty((3, 3))
    Rk = np.empty((3, 3))
    origins = np.empty((n_q, 3))
    axes = np.empty((n_q, 3))
    A = np.empty((6, n_q))
    S = np.empty((6, 6))
    e = np.empty(6)
    x = np.empty(6)
    p = np.empty(3)
    z = np.empty(3)
    contact = np.empty(3)
    for n in range(Q.shape[0]):
        q = Q[n]
        t = targets[n]
        a = axis_targets[n]
        for iteration in range(max_iterations + 1):
            # forward kinematics: joint frames, contact point, tool axis
            for i in range(3):
                p[i] = 0.0
                for j in range(3):
                    R[i, j] = 1.0 if i == j else 0.0
            for k in range(n_q):
                for i in range(3):
                    p[i] += R[i, 0] * p_joint[k, 0] + R[i, 1] * p_joint[k, 1] + R[i, 2] * p_joint[k, 2]
                for i in range(3):
                    for j in range(3):
                        Rk[i, j] = R[i, 0] * R_joint[k, 0, j] + R[i, 1] * R_joint[k, 1, j] + R[i, 2] * R_joint[k, 2, j]
                c, s = np.cos(q[k]), np.sin(q[k])
                for i in range(3):
                    R[i, 0] = c * Rk[i, 0] + s * Rk[i, 1]
                    R[i, 1] = c * Rk[i, 1] - s * Rk[i, 0]
                    R[i, 2] = Rk[i, 2]
                    origins[k, i] = p[i]
                    axes[k, i] = R[i, 2]
            for i in range(3):
                contact[i] = p[i] + R[i, 0] * p_contact[0] + R[i, 1] * p_contact[1] + R[i, 2] * p_contact[2]
                z[i] = R[i, 0] * z_contact[0] + R[i, 1] * z_contact[1] + R[i, 2] * z_contact[2]
            # errors
            for i in range(3):
                e[i] = t[i] - contact[i]
            e[3] = z[1] * a[2] - z[2] * a[1]
            e[4] = z[2] * a[0] - z[0] * a[2]
            e[5] = z[0] * a[1] - z[1] * a[0]
            pe = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            ae = np.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5])
            position_error[n] = pe
            axis_error[n] = ae
            aligned = z[0] * a[0] + z[1] * a[1] + z[2] * a[2] > 0.0
            if pe < position_tolerance and ae < axis_tolerance and aligned:
                reachable[n] = True
                break
            if iteration == max_iterations:
                break
            if not aligned:
                # turn about any normal axis: z x (a + 0.5 z x roll(z))
                r0, r1, r2 = z[2], z[0], z[1]
                w0 = a[0] + 0.5 * (z[1] * r2 - z[2] * r1)
                w1 = a[1] + 0.5 * (z[2] * r0 - z[0] * r2)
                w2 = a[2] + 0.5 * (z[0] * r1 - z[1] * r0)
                e[3] = z[1] * w2 - z[2] * w1
                e[4] = z[2] * w0 - z[0] * w2
                e[5] = z[0] * w1 - z[1] * w0
            # A = [Jv; (I - z z^T) Jw]
            for k in range(n_q):
                dx, dy, dz = contact[0] - origins[k, 0], contact[1] - origins[k, 1], contact[2] - origins[k, 2]
                wx, wy, wz = axes[k, 0], axes[k, 1], axes[k, 2]
                A[0, k] = wy * dz - wz * dy
                A[1, k] = wz * dx - wx * dz
                A[2, k] = wx * dy - wy * dx
                zw = z[0] * wx + z[1] * wy + z[2] * wz
                A[3, k] = wx - z[0] * zw
                A[4, k] = wy - z[1] * zw
                A[5, k] = wz - z[2] * zw
            # S = A A^T + lambda^2 I, Cholesky S = L L^T in place (lower triangle)
            for i in range(6):
                for j in range(i + 1):
                    acc = 0.0
                    for k in range(n_q):
                        acc += A[i, k] * A[j, k]
                    S[i, j] = acc + (damping_squared if i == j else 0.0)
            for j in range(6):
                d = S[j, j]
                for k in range(j):
                    d -= S[j, k] * S[j, k]
                d = np.sqrt(d)
                S[j, j] = d
                for i in range(j + 1, 6):
                    v = S[i, j]
                    for k in range(j):
                        v -= S[i, k] * S[j, k]
                    S[i, j] = v / d
            for i in range(6):
                v = e[i]
                for k in range(i):
                    v -= S[i, k] * x[k]
                x[i] = v / S[i, i]
            for i in range(5, -1, -1):
                v = x[i]
                for k in range(i + 1, 6):
                    v -= S[k, i] * x[k]
                x[i] = v / S[i, i]
            for k in range(n_q):
                step = 0.0
                for i in range(6):
                    step += A[i, k] * x[i]
                step = min(max(step, -max_step), max_step)
                q[k] = min(max(q[k] + step, q_min[k]), q_max[k])
