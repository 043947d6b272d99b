"""The one inverse kinematics: joint postures that put the contact frame on a target, by damped
least squares within the joint limits.

Every use runs the same iteration from a seed posture q_0 (clipped into the limits). A target
gives, at the iterate q, a task error e(q) and a matrix A(q) with de/dt = -A dq to first order;
each step solves

  dq = A^T (A A^T + lambda^2 I)^-1 e        (= (A^T A + lambda^2 I)^-1 A^T e, damped Gauss-Newton)

limited to ``MAX_STEP`` rad per joint and clipped to the joint limits, until the errors fall
below their tolerances or the steps are spent (:class:`Stop`). The
solution is the posture of the nearest local minimum from the seed, which is why a sweep
documents its seed (docs/sweep.md). Two targets, two uses:

- **Contact posture** (:func:`contact_posture`, the sweep's postures): the tool tip on a surface
  point p* and the tool axis (hand z) along -n, five dimensions (the spin about the axis is
  free). With the world-aligned frame Jacobian J6 = [Jv; Jw],

    e_p = p* - p,          de_p/dt = -Jv dq
    e_z = z x (-n),        the rotation that turns z onto -n, of norm sin(angle); the angular
                           velocity that reduces it is w = e_z, reached by P Jw dq with
                           P = I - z z^T (the spin w.z does not move the axis),

  so A = [Jv; P Jw] and e = [e_p; e_z].
- **Approach start** (:func:`approach_start`, the start of every simulated trial): the whole
  pose T* of the contact frame, six dimensions. The error is the twist e = log6(T^-1 T*) in the
  contact frame and A = Jlog6(T^-1 T*) J_local, with J_local the frame Jacobian in the contact
  frame (the position error is |e[:3]|, the axis error |e[3:]|, in rad).

:func:`contact_postures` runs the contact-posture iteration for N targets (every target from
the same seed, each one stopped at its own convergence) in a compiled kernel, with the forward
kinematics of ``controller.model.batch.BatchKinematics`` written out and the 6x6 system solved by
Cholesky; it reaches the postures of :func:`contact_posture` up to rounding (its plain-numpy
reference lives with the tests).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit

from .batch import BatchKinematics
from .postures import Surface
from .robot import PandaModel
from .validation import BadInputError

POSITION_TOLERANCE = 1e-6
"""Largest tip position error (m) of a reached posture."""

AXIS_TOLERANCE = 1e-5
"""Largest |z x (-n)| (sin of the axis angle error) of a reached contact posture, and largest
rotation error (rad) of a reached pose."""

DAMPING = 1e-3
MAX_STEP = 0.2
MAX_ITERATIONS = 200


class Stop(NamedTuple):
    """When the iteration stops: both errors below their tolerances, or ``iterations`` steps."""

    position: float = POSITION_TOLERANCE
    axis: float = AXIS_TOLERANCE
    iterations: int = MAX_ITERATIONS


APPROACH_STOP = Stop(1e-7, 1e-6, 100)
"""The approach start is placed ten times tighter (m, rad) than a contact posture: the start
distance and the tool orientation of every simulated trial come from it."""


class UnreachableStartError(BadInputError):
    """No joint posture puts the tool at the requested start pose (wall out of reach)."""


@dataclass(frozen=True)
class ContactPosture:
    """The result of the iteration: the last iterate and whether it reaches the target."""

    q: np.ndarray
    reachable: bool
    position_error: float  # m
    axis_error: float  # sin of the angle between the tool axis and -n (rad for a pose)


TaskError = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, float, bool]]
"""A target of the iteration: the iterate q -> (e, A, axis error, aligned), e and A as in the
module docstring with e[:3] the position error; ``aligned`` False keeps the iteration going."""


def solve(robot: PandaModel, task: TaskError, seed, stop: Stop = Stop()) -> ContactPosture:
    """The damped least-squares iteration of the module docstring on the target ``task``."""
    q = np.clip(np.asarray(seed, dtype=float), robot.q_min, robot.q_max)
    position_error = axis_error = np.inf
    for iteration in range(stop.iterations + 1):
        e, A, axis_error, aligned = task(q)
        position_error = float(np.linalg.norm(e[:3]))
        if position_error < stop.position and axis_error < stop.axis and aligned:
            return ContactPosture(q, True, position_error, axis_error)
        if iteration == stop.iterations:
            break
        step = limited_step(A, e, q, robot)
        q = np.clip(q + np.clip(step, -MAX_STEP, MAX_STEP), robot.q_min, robot.q_max)
    return ContactPosture(q, False, position_error, axis_error)


def limited_step(A: np.ndarray, e: np.ndarray, q: np.ndarray, robot: PandaModel) -> np.ndarray:
    """The damped least-squares step dq = A^T (A A^T + lambda^2 I)^-1 e over the joints that are
    free to move: a joint at a limit whose step would push it further out is frozen (its column
    of A zeroed) and the step recomputed, so the other joints take up its share instead of the
    clipped step stalling the iteration."""
    frozen = np.zeros(q.size, dtype=bool)
    regularised = DAMPING**2 * np.eye(e.size)
    while True:
        free = np.where(frozen, 0.0, A)
        step = free.T @ np.linalg.solve(free @ free.T + regularised, e)
        blocked = ~frozen & (((q <= robot.q_min) & (step < 0.0)) | ((q >= robot.q_max) & (step > 0.0)))
        if not blocked.any():
            return step
        frozen |= blocked


def tip_and_axis(robot: PandaModel, point, normal) -> TaskError:
    """The contact-posture target: the tip at ``point``, hand z along -``normal`` (5 rows)."""
    target = np.asarray(point, dtype=float)
    axis_target = -np.asarray(normal, dtype=float)
    model, data, fid = robot.model, robot.data, robot.contact_frame_id
    A = np.empty((6, robot.q_min.size))
    e = np.empty(6)

    def task(q: np.ndarray):
        J6 = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        placement = data.oMf[fid]
        z = placement.rotation[:, 2]
        e[:3] = target - placement.translation
        e[3:] = np.cross(z, axis_target)
        axis_error = float(np.linalg.norm(e[3:]))
        aligned = float(z @ axis_target) > 0.0
        if not aligned:
            # Pointing away: the cross product vanishes at 180 degrees; turn about any normal axis.
            e[3:] = np.cross(z, axis_target + 0.5 * np.cross(z, np.roll(z, 1)))
        A[:3] = J6[:3]
        A[3:] = J6[3:] - np.outer(z, z @ J6[3:])
        return e, A, axis_error, aligned

    return task


def pose(robot: PandaModel, target: pin.SE3) -> TaskError:
    """The approach-start target: the whole pose ``target`` of the contact frame (6 rows)."""
    model, data, fid = robot.model, robot.data, robot.contact_frame_id

    def task(q: np.ndarray):
        pin.framesForwardKinematics(model, data, q)
        offset = data.oMf[fid].actInv(target)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        e = pin.log6(offset).vector
        return e, pin.Jlog6(offset) @ J, float(np.linalg.norm(e[3:])), True

    return task


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
    return solve(robot, tip_and_axis(robot, point, normal), seed, Stop(iterations=max_iterations))


def approach_pose(robot: PandaModel, q_contact: np.ndarray, surface: Surface, distance: float) -> pin.SE3:
    """The pose ``distance`` in front of ``surface`` that an approach from ``q_contact`` starts at.

    Its point is the posture's contact point projected on the surface plane, moved by
    ``distance`` along the normal n; its orientation is the posture's, turned by the smallest
    rotation that maps its tool axis (hand z) onto -n.
    """
    start = robot.contact_frame(q_contact)
    turn = pin.Quaternion.FromTwoVectors(start.rotation[:, 2], -surface.normal).toRotationMatrix()
    point = start.translation - surface.signed_distance(start.translation) * surface.normal
    return pin.SE3(turn @ start.rotation, point + distance * surface.normal)


def approach_start(robot: PandaModel, q_contact, surface: Surface, distance: float) -> np.ndarray:
    """Joint posture with the contact frame at :func:`approach_pose`, from the seed ``q_contact``.

    The iteration stops at ``APPROACH_STOP``. Raises :class:`UnreachableStartError` when it
    does not reach that pose.
    """
    if not (np.isfinite(distance) and distance >= 0.0):
        raise BadInputError(f"start distance {distance} m must be >= 0")
    q_contact, _ = robot.check_state(q_contact)
    target = approach_pose(robot, q_contact, surface, distance)
    solved = solve(robot, pose(robot, target), q_contact, APPROACH_STOP)
    if solved.reachable:
        return solved.q
    raise UnreachableStartError(
        f"the tool cannot reach {np.round(target.translation, 3).tolist()} (m, world) with its axis "
        f"along {np.round(-surface.normal, 3).tolist()}: the surface through "
        f"{np.round(surface.point, 3).tolist()} with normal {np.round(surface.normal, 3).tolist()} "
        f"is out of reach from this posture (residual {np.hypot(solved.position_error, solved.axis_error):.3g})"
    )


@dataclass(frozen=True)
class ContactPostures:
    """The result of :func:`contact_postures`: one row per target, as in :class:`ContactPosture`."""

    q: np.ndarray  # (N, nq)
    reachable: np.ndarray  # (N,) bool
    position_error: np.ndarray  # (N,) m
    axis_error: np.ndarray  # (N,)

    @classmethod
    def unsolved(cls, robot: PandaModel, points, normals, seed) -> tuple[np.ndarray, np.ndarray, ContactPostures]:
        """The targets (N, 3), the tool-axis targets -n (N, 3) and the start of a batch: the
        seeds (N, nq) clipped into the limits, not reachable, infinite errors."""
        targets = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
        axis_targets = -np.ascontiguousarray(normals, dtype=float).reshape(-1, 3)
        n = targets.shape[0]
        Q = np.tile(np.clip(np.asarray(seed, dtype=float), robot.q_min, robot.q_max), (n, 1))
        return targets, axis_targets, cls(Q, np.zeros(n, dtype=bool), np.full(n, np.inf), np.full(n, np.inf))


class KinematicChain(NamedTuple):
    """The kinematic chain of ``BatchKinematics`` and the joint limits, as the kernel reads them."""

    R_joint: np.ndarray  # (joints, 3, 3) fixed rotation of each joint frame in its parent
    p_joint: np.ndarray  # (joints, 3) its origin in the parent
    p_contact: np.ndarray  # (3,) contact point in the last joint frame
    z_contact: np.ndarray  # (3,) tool axis in the last joint frame
    q_min: np.ndarray
    q_max: np.ndarray


class Iteration(NamedTuple):
    """The constants of the iteration, as the kernel reads them."""

    max_iterations: int
    damping_squared: float
    max_step: float
    position_tolerance: float
    axis_tolerance: float


def contact_postures(
    kinematics: BatchKinematics,
    points,
    normals,
    seed,
    max_iterations: int = MAX_ITERATIONS,
) -> ContactPostures:
    """:func:`contact_posture` for N targets (``points`` and unit ``normals``, (N, 3)), compiled."""
    robot = kinematics.robot
    targets, axis_targets, result = ContactPostures.unsolved(robot, points, normals, seed)
    chain = KinematicChain(
        kinematics.R_joint, kinematics.p_joint, kinematics.p_contact,
        np.ascontiguousarray(kinematics.R_contact[:, 2]), robot.q_min, robot.q_max,
    )
    iteration = Iteration(int(max_iterations), DAMPING**2, MAX_STEP, POSITION_TOLERANCE, AXIS_TOLERANCE)
    contact_postures_kernel(
        result.q, targets, axis_targets, chain, iteration, result.reachable, result.position_error, result.axis_error
    )
    return result


@njit(cache=True)
def contact_postures_kernel(Q, targets, axis_targets, chain, iteration, reachable, position_error, axis_error):
    """Kernel of :func:`contact_postures`: the iteration of :func:`contact_posture` for each row
    of ``Q`` (the seeds, updated in place to the last iterates) with the forward kinematics of
    ``BatchKinematics`` written out (``chain``, a :class:`KinematicChain`), the constants of
    ``iteration`` (an :class:`Iteration`), and (A A^T + lambda^2 I) x = e solved by Cholesky.
    Longer than 80 lines: one compiled loop, written out so that it allocates nothing per step."""
    R_joint, p_joint, p_contact, z_contact, q_min, q_max = chain
    max_iterations, damping_squared, max_step, position_tolerance, axis_tolerance = iteration
    n_q = Q.shape[1]
    R = np.empty((3, 3))
    Rk = np.empty((3, 3))
    origins = np.empty((n_q, 3))
    axes = np.empty((n_q, 3))
    A = np.empty((6, n_q))
    S = np.empty((6, 6))
    e = np.empty(6)
    x = np.empty(6)
    steps = np.empty(n_q)
    frozen = np.zeros(n_q, dtype=np.bool_)
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
            # the step over the free joints (``limited_step``): a joint at a limit that the step
            # pushes further out is frozen (its column of A zeroed) and the step recomputed
            for k in range(n_q):
                frozen[k] = False
            blocked = True
            while blocked:
                # S = A A^T + lambda^2 I over the free columns, Cholesky S = L L^T in place
                for i in range(6):
                    for j in range(i + 1):
                        acc = 0.0
                        for k in range(n_q):
                            if not frozen[k]:
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
                blocked = False
                for k in range(n_q):
                    step = 0.0
                    if not frozen[k]:
                        for i in range(6):
                            step += A[i, k] * x[i]
                        if (q[k] <= q_min[k] and step < 0.0) or (q[k] >= q_max[k] and step > 0.0):
                            frozen[k] = True
                            blocked = True
                    steps[k] = step
            for k in range(n_q):
                step = min(max(steps[k], -max_step), max_step)
                q[k] = min(max(q[k] + step, q_min[k]), q_max[k])
