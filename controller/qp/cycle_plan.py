"""The compiled cycle plan: every task and constraint row of one control cycle in ONE compiled call.

The generic assembly (``ImpactAwareController._assemble_tasks`` and ``_assemble_constraints``)
asks each task and constraint for its rows, one Python call each, then builds the QP cost and
intersects the boxes: about a microsecond of interpreter work per object and per step. When
every task and constraint of a controller has a compiled kernel (the classes of
``KERNEL_KINDS``, frictionless impact rows), the plan is built once, at the controller's
construction:

- a table, one line per object: its kernel's kind, its first row (a task's in the stacked task
  rows, a general constraint's in C; a box's index in the box bounds), its number of rows, the
  offset of its parameters in one packed array, and the index of its expected impact;
- the packed parameters: each object's ``kernel_parameters()`` (gains, targets, weights,
  limits) one after the other, packed again only when a task's or a constraint's attribute was
  assigned since (``Task.parameter_edits``, ``Constraint.parameter_edits``), not per cycle.

At each cycle ``fill`` reads the jump matrices and the activation of each expected impact (once
per fill of the model terms, shared with the Command's prediction) and makes one call of
``planned_rows``, which runs the classes' own kernels on their slices of the stacked buffers:
the task rows, the cost H = A^T W A, g = -A^T W b, the box bounds and their intersection clipped
into the cycle's reachable accelerations, the general rows, and the relaxed rows relaxed to what
that box reaches (``ControlCycle.recoverable``). The QP it writes is the generic assembly's, the
same kernels on the same inputs; a controller with any other task or constraint (a user's
class or subclass, a frame or surface-offset task, the held contacts' rows) assembles
generically.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from impactqp.constraints import (
    AccelerationLimit, Constraint, ControlCycle, ImpulsiveTorqueLimit, PositionLimit, PostImpactVelocityLimit,
    TorqueLimit, VelocityLimit,
)
from impactqp.constraints.constraint import relax_to_reachable
from impactqp.constraints.impulsive_torque import edge_scaled_impulse_rows
from impactqp.constraints.position_limit import braking_bounds
from impactqp.constraints.post_impact_velocity import edge_post_impact_velocity_rows
from impactqp.constraints.torque_limit import normalised_torque_rows
from impactqp.constraints.velocity_limit import symmetric_velocity_bounds
from impactqp.controller.model.model_terms import ModelTerms
from impactqp.tasks import ContactApproachTask, DampingTask, PostureTask, Task
from impactqp.tasks.contact_approach_task import APPROACH_REFERENCE_SIZE, surface_frame_approach_rows
from impactqp.tasks.posture_task import joint_pd_rows

from .cycle_kernels import intersect_boxes, weighted_least_squares
from .problem import ConstraintLayout, QpProblem

# Kinds of kernel: tasks below 10, boxes from 10, general rows from 20.
APPROACH, POSTURE, DAMPING = 1, 2, 3
ACCELERATION, POSITION, VELOCITY = 10, 11, 12
TORQUE, POST_IMPACT, IMPULSIVE = 20, 21, 22
KERNEL_KINDS = {
    ContactApproachTask: APPROACH, PostureTask: POSTURE, DampingTask: DAMPING,
    AccelerationLimit: ACCELERATION, PositionLimit: POSITION, VelocityLimit: VELOCITY,
    TorqueLimit: TORQUE, PostImpactVelocityLimit: POST_IMPACT, ImpulsiveTorqueLimit: IMPULSIVE,
}
"""The classes with a kernel of the plan (exactly these classes: a subclass may change the rows)."""

KIND, FIRST, ROWS, PARAMETERS, IMPACT = range(5)  # the columns of the plan's table


@dataclass(frozen=True, eq=False)
class CycleBuffers:
    """The controller's preallocated arrays the plan writes: the stacked task rows A, b and
    their weights w (one per row), the QP, and the box bounds (rows 2k and 2k + 1: box k)."""

    task_A: np.ndarray
    task_b: np.ndarray
    task_w: np.ndarray
    problem: QpProblem
    box_bounds: np.ndarray


class CyclePlan:
    """The compiled plan of one controller's tasks and constraints (module docstring); ``of``
    gives None when one of them has no kernel of the plan (one of ``kinds``)."""

    kinds = KERNEL_KINDS

    def __init__(self, objects: list, table: np.ndarray, impacts: list, buffers: CycleBuffers, dt: float, first_relaxed: int):
        self.objects, self.table, self.impacts, self.buffers, self.dt = objects, table, impacts, buffers, dt
        self.first_relaxed = first_relaxed  # the first relaxed row of C
        n = buffers.problem.H.shape[0]
        self.parameters = np.empty(0)
        self._edits = (-1, -1)  # the parameter edits of the last packing
        self._active = np.zeros(max(len(impacts), 1), dtype=np.bool_)
        self._no_impact = ((np.zeros((n, n)),), (np.zeros((0, n, n)),))  # a plan without impact rows: A or P; edges

    @classmethod
    def of(cls, tasks: list[Task], layout: ConstraintLayout, buffers: CycleBuffers, dt: float) -> CyclePlan | None:
        """The plan of ``tasks`` (in the order of their stacked rows) and of the constraints of
        ``layout``, or None when one of them has no kernel of the plan."""
        n = buffers.problem.H.shape[0]
        objects = [*tasks, *layout.box_constraints, *layout.row_constraints]
        if not all(_planned(cls.kinds.get(type(item)), item, n) for item in objects):
            return None
        impacts: list = []
        for constraint in layout.row_constraints:
            impact = getattr(constraint, "impact", None)
            if impact is not None and not any(impact is known for known in impacts):
                impacts.append(impact)
        table = np.zeros((len(objects), 5), dtype=np.int64)
        task_row = 0
        for line, task in zip(table, tasks):
            line[KIND], line[FIRST], line[ROWS] = cls.kinds[type(task)], task_row, task.rows
            task_row += task.rows
        boxes = len(layout.box_constraints)
        for k, constraint in enumerate(layout.box_constraints):
            line = table[len(tasks) + k]
            line[KIND], line[FIRST], line[ROWS] = cls.kinds[type(constraint)], k, constraint.rows or n
        for line, constraint, rows in zip(table[len(tasks) + boxes:], layout.row_constraints, layout.row_slices):
            line[KIND], line[FIRST], line[ROWS] = cls.kinds[type(constraint)], rows.start, constraint.rows
            impact = getattr(constraint, "impact", None)
            line[IMPACT] = next((i for i, known in enumerate(impacts) if known is impact), 0)
        return cls(objects, table, impacts, buffers, dt, layout.first_relaxed_row)

    def pack(self) -> None:
        """The objects' ``kernel_parameters`` into the packed array and their offsets into the table."""
        packed = [
            item.kernel_parameters(self.dt) if isinstance(item, PositionLimit) else item.kernel_parameters()
            for item in self.objects
        ]
        sizes = np.array([len(values) for values in packed], dtype=np.int64)
        self.table[:, PARAMETERS] = np.cumsum(sizes) - sizes
        self.parameters = np.concatenate(packed) if packed else np.empty(0)
        self._edits = (Task.parameter_edits, Constraint.parameter_edits)

    def _impact_maps(self, terms: ModelTerms) -> tuple:
        """The kernels' ``impacts``: (A, P, the edges' A_i, the edges' P_i), one entry per expected
        impact (zeros when there is none), and their activations at ``terms``."""
        active = self._active
        if not self.impacts:
            (matrix,), (edge,) = self._no_impact
            return (matrix,), (matrix,), (edge,), (edge,), active
        jumps, torques, edge_jumps, edge_torques = [], [], [], []
        for i, impact in enumerate(self.impacts):
            matrices, edges = impact.row_matrices(terms), impact.edge_row_matrices(terms)
            jumps.append(matrices.jump_matrix)
            torques.append(matrices.torque_matrix)
            edge_jumps.append(edges.jump)
            edge_torques.append(edges.torque)
            active[i] = impact.is_active(terms)
        return tuple(jumps), tuple(torques), tuple(edge_jumps), tuple(edge_torques), active

    def fill(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Every task and constraint row of this state into the buffers (one compiled call);
        False when the box bounds conflict."""
        if self._edits != (Task.parameter_edits, Constraint.parameter_edits):
            self.pack()
        maps = self._impact_maps(terms)
        b = self.buffers
        p = b.problem
        return planned_rows(
            (terms.q, terms.dq, terms.J6, terms.dJ6_dq, terms.contact_rotation, terms.M, terms.h), maps,
            (cycle.acceleration_lower, cycle.acceleration_upper, cycle.horizon, cycle.dt),
            self.table, self.parameters, (b.task_A, b.task_b, b.task_w),
            (p.H, p.g, b.box_bounds, p.lower, p.upper, p.C), self.first_relaxed,
        )


def _planned(kind: int | None, item, variables: int) -> bool:
    """Whether a plan has a kernel for ``item`` of kernel kind ``kind`` (None: its class has
    none) among ``variables`` velocities: torque and impulse rows on every velocity, damping rows
    one per velocity (the kernels' shapes)."""
    if kind == DAMPING:
        return item.rows == variables
    if kind == TORQUE:
        return item.rows == variables
    if kind == IMPULSIVE:
        return len(item.impulse_limit) == variables
    return kind is not None


@njit(cache=True)
def planned_rows(state, impacts, cycle, table, parameters, task_rows, qp, first_relaxed):
    """Kernel of ``CyclePlan.fill``: ``state`` = (q, dq, J6, dJ6 dq, R, M, h), ``impacts`` = (the
    jump matrices A, the torque maps P, the edges' A_i, the edges' P_i, the activations), one
    entry per expected impact, ``cycle`` = (the
    reachable lower and upper accelerations, the horizon h, dt), ``task_rows`` = (A, b, w),
    ``qp`` = (H, g, the box bounds, [lb; l], [ub; u], C). Each line of ``table`` runs its class's
    kernel on its slice with its ``parameters`` (the layouts of the classes'
    ``kernel_parameters``); then H = A^T W A, g = -A^T W b, the boxes intersected into
    [lb, ub] within the reachable interval, and the rows from ``first_relaxed`` on relaxed to
    what [lb, ub] reaches. False when the boxes conflict."""
    task_A, task_b, task_w = task_rows
    H, g, box_bounds, lower, upper, C = qp
    n = task_A.shape[1]
    planned_task_rows(state, table, parameters, task_rows)
    weighted_least_squares(task_A, task_b, task_w, H, g)
    consistent = planned_boxes(state, cycle, table, parameters, box_bounds, lower, upper)
    planned_general_rows(state, impacts, cycle[2], table, parameters, qp)
    relax_to_reachable(C[first_relaxed:], lower[n + first_relaxed:], upper[n + first_relaxed:], lower[:n], upper[:n])
    return consistent


@njit(cache=True)
def planned_task_rows(state, table, parameters, task_rows):
    """Kernel: the rows of the approach, posture and damping tasks of ``table`` (the other lines
    left as they are), for ``planned_rows``'s ``state`` and ``task_rows``."""
    q, dq, J6, dJ6_dq, rotation = state[0], state[1], state[2], state[3], state[4]
    task_A, task_b, task_w = task_rows
    n, joints = dq.shape[0], q.shape[0]
    for e in range(table.shape[0]):
        kind, first, rows, p = table[e, KIND], table[e, FIRST], table[e, ROWS], table[e, PARAMETERS]
        last = first + rows
        if kind == APPROACH:
            reference_end = p + APPROACH_REFERENCE_SIZE
            surface_frame_approach_rows(
                J6, dq, dJ6_dq, rotation, parameters[p:reference_end], task_A[first:last], task_b[first:last]
            )
            task_w[first:last] = parameters[reference_end:reference_end + 6]
        elif kind == POSTURE:
            task_A[first:last, :n - rows] = 0.0
            joint_pd_rows(
                q[joints - rows:], dq[n - rows:], parameters[p + 2:p + 2 + rows], parameters[p], parameters[p + 1],
                task_A[first:last, n - rows:], task_b[first:last],
            )
            task_w[first:last] = parameters[p + 2 + rows:p + 2 + 2 * rows]
        elif kind == DAMPING:
            joint_pd_rows(dq, dq, dq, 0.0, parameters[p], task_A[first:last], task_b[first:last])
            task_w[first:last] = parameters[p + 1:p + 1 + rows]


@njit(cache=True)
def planned_boxes(state, cycle, table, parameters, box_bounds, lower, upper):
    """Kernel: the bounds of the box constraints of ``table`` (acceleration, position and
    velocity limits) into ``box_bounds``, then intersected into lower[:n], upper[:n] within the
    reachable interval of ``cycle``; False when they conflict."""
    q, dq = state[0], state[1]
    reach_lower, reach_upper, horizon, dt = cycle
    n, joints = dq.shape[0], q.shape[0]
    inv_h = 1.0 / horizon
    for e in range(table.shape[0]):
        kind, k, rows, p = table[e, KIND], table[e, FIRST], table[e, ROWS], table[e, PARAMETERS]
        box_lower, box_upper = box_bounds[2 * k], box_bounds[2 * k + 1]
        if kind == ACCELERATION:
            box_lower[:] = reach_lower
            box_upper[:] = reach_upper
        elif kind == POSITION:
            box_lower[:n - rows] = -np.inf
            box_upper[:n - rows] = np.inf
            braking_bounds(
                q[joints - rows:], dq[n - rows:], parameters[p:p + 2 * rows].reshape((2, rows)),
                parameters[p + 2 * rows:p + 5 * rows].reshape((3, rows)), dt, box_lower[n - rows:], box_upper[n - rows:],
            )
        elif kind == VELOCITY:
            box_lower[:n - rows] = -np.inf
            box_upper[:n - rows] = np.inf
            symmetric_velocity_bounds(dq[n - rows:], parameters[p:p + rows], inv_h, box_lower[n - rows:], box_upper[n - rows:])
    return intersect_boxes(box_bounds[0::2], box_bounds[1::2], reach_lower, reach_upper, lower[:n], upper[:n])


@njit(cache=True)
def planned_general_rows(state, impacts, horizon, table, parameters, qp):
    """Kernel: the general rows of the torque, post-impact velocity and impulsive torque limits
    of ``table`` (``planned_rows``'s ``state``, ``impacts`` and ``qp``; ``horizon``: h)."""
    dq, M, h = state[1], state[5], state[6]
    jumps, torques, edge_jumps, edge_torques, active = impacts
    C, lower, upper = qp[5], qp[3], qp[4]
    n = dq.shape[0]
    inv_h = 1.0 / horizon
    for e in range(table.shape[0]):
        kind, first, rows, p, i = table[e, KIND], table[e, FIRST], table[e, ROWS], table[e, PARAMETERS], table[e, IMPACT]
        last = first + rows
        if kind == TORQUE:
            normalised_torque_rows(M, h, parameters[p:p + rows], C[first:last], lower[n + first:n + last], upper[n + first:n + last])
        elif kind == POST_IMPACT:  # a block of rows per map: A, then each edge's A_i
            block = rows // (1 + edge_jumps[i].shape[0])
            edge_post_impact_velocity_rows(
                (jumps[i], edge_jumps[i]), dq, parameters[p:p + block], inv_h, active[i], C[first:last],
                lower[n + first:n + last], upper[n + first:n + last],
            )
        elif kind == IMPULSIVE:  # P, then each edge's P_i
            edge_scaled_impulse_rows(
                (torques[i], edge_torques[i]), parameters[p:p + 2 * n].reshape((2, n)), dq, inv_h, active[i],
                C[first:last], lower[n + first:n + last], upper[n + first:n + last],
            )
