"""Plain-numpy reference of ``controller.model.inverse_kinematics.contact_postures``."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.inverse_kinematics import (
    AXIS_TOLERANCE,
    DAMPING,
    MAX_ITERATIONS,
    MAX_STEP,
    POSITION_TOLERANCE,
    ContactPostures,
)


def reference_contact_postures(
    kinematics: BatchKinematics,
    points,
    normals,
    seed,
    max_iterations: int = MAX_ITERATIONS,
) -> ContactPostures:
    """``contact_postures`` in plain numpy (the reference of its kernel).

    Each iteration evaluates the frames of the targets still unsolved (``contact_frames``), tests
    them with the same tolerances and takes the same damped least-squares step (batched 6x6 solves).
    """
    robot = kinematics.robot
    targets, axis_targets, result = ContactPostures.unsolved(robot, points, normals, seed)
    Q, reachable, position_error, axis_error = result.q, result.reachable, result.position_error, result.axis_error
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
        step = np.array([free_joint_step(A[n], e[n], q[n], robot, damping) for n in range(q.shape[0])]).reshape(q.shape)
        Q[active] = np.clip(q + np.clip(step, -MAX_STEP, MAX_STEP), robot.q_min, robot.q_max)
    return result


def free_joint_step(A, e, q, robot, damping):
    """The damped least-squares step over the joints free to move: joints at a limit that the
    step pushes further out are left out (columns of A zeroed), one at a time until none is."""
    frozen = np.zeros(q.size, dtype=bool)
    while True:
        A_free = A * ~frozen
        step = A_free.T @ np.linalg.solve(A_free @ A_free.T + damping, e)
        blocked = ~frozen & (((q <= robot.q_min) & (step < 0.0)) | ((q >= robot.q_max) & (step > 0.0)))
        if not blocked.any():
            return step
        frozen |= blocked
