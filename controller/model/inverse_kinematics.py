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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

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
