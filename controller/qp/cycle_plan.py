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
- the packed parameters: h, dt and the first relaxed row (``HEAD``), then each object's
  ``kernel_parameters()`` (gains, targets, weights, limits) one after the other, packed again only when a task's or a constraint's attribute was
  assigned since (``Task.parameter_edits``, ``Constraint.parameter_edits``), not per cycle.

At each cycle ``fill`` has each expected impact write its jump matrices into the plan's
stacked buffers (``ExpectedImpact.fill_stacked``: the fixed base's fills write there directly,
once per fill of the model terms, shared with the Command's prediction), or, when every impact
is a fixed base's crb, gm or classical impact, without friction rows or with a pyramid's
(``ExpectedImpact.plan_updates_it``), lets the kernel update them (``stacked_updates``: A, P,
G, the edges' maps and the activation, from their rule values and edge directions packed after
the parameters) and tells each impact (``adopt_stacked``). It makes one
call of ``planned_rows`` on flat arrays only (numba types each argument at every call, a tuple
element by element; an array's type does not depend on its shape, so one compiled signature
serves every number of impacts and every robot), eight of them: the arm's state in one array
(``ModelTerms.arm_state``), M, h, the expected impacts' rows (their maps and activations), the
table, the parameters (h, dt, the first relaxed row, the buffers' sizes and the number of
impacts the kernel updates at their head), the controller's buffers (``CycleBuffers``: the
reachable accelerations, the task rows, the QP and the box bounds, views of one array) and the
locked robot's centre of mass, inertia about it and mass (``ModelTerms.locked_body``, what the
crb update reads; the gm and classical ones read M). It runs the
classes' own kernels on their slices of the stacked buffers:
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
from impactqp.constraints.impact_cycle_kernels import RULE_VALUES, stacked_updates
from impactqp.constraints.impact_model import ExpectedImpact
from impactqp.constraints.impulsive_torque import edge_scaled_impulse_rows
from impactqp.constraints.position_limit import braking_bounds
from impactqp.constraints.post_impact_velocity import edge_post_impact_velocity_rows
from impactqp.constraints.torque_limit import normalised_torque_rows
from impactqp.constraints.velocity_limit import symmetric_velocity_bounds
from impactqp.controller.model.model_terms import CONTACT_TERMS_EXTRA, ModelTerms, arm_state_views
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
HORIZON, DT, FIRST_RELAXED, TASK_ROWS, GENERAL_ROWS, BOXES, RULES = range(7)  # the head of the packed parameters
HEAD = 7


@dataclass(frozen=True, eq=False)
class CycleBuffers:
    """The controller's preallocated arrays the plan writes, views of one flat array ``data``
    (``cycle_buffer_views``: the plan's kernel reads them in one argument): the reachable
    accelerations (the controller's ``ControlCycle`` holds their two rows), the stacked task
    rows A, b and their weights w (one per row), the QP (``QpProblem.over`` its H, g, C and
    bounds) and the box bounds (rows 2k and 2k + 1: box k)."""

    data: np.ndarray
    reachable_lower: np.ndarray
    reachable_upper: np.ndarray
    task_A: np.ndarray
    task_b: np.ndarray
    task_w: np.ndarray
    problem: QpProblem
    box_bounds: np.ndarray

    @classmethod
    def empty(cls, variables: int, task_rows: int, rows: int, boxes: int) -> CycleBuffers:
        """Zeros for ``task_rows`` task rows, ``rows`` general rows and ``boxes`` box
        constraints in ``variables`` unknowns."""
        n = variables
        data = np.zeros(n * (2 + task_rows + n + 1 + rows + 2 * boxes) + 2 * task_rows + 2 * (n + rows))
        reachable, task_A, task_b, task_w, H, g, C, bounds, box_bounds = cycle_buffer_views(data, n, task_rows, rows, boxes)
        return cls(data, reachable[0], reachable[1], task_A, task_b, task_w, QpProblem.over(H, g, C, bounds), box_bounds)


@njit(cache=True)
def cycle_buffer_views(data, n, task_rows, rows, boxes):
    """The views (reachable lower and upper accelerations (2 x n), task A (task_rows x n), b,
    w, H (n x n), g, C (rows x n), bounds [[lb; l], [ub; u]] (2 x (n + rows)), box bounds
    (2 boxes x n)) of ``data``, one after the other (``CycleBuffers``), for kernels and for
    Python alike."""
    sizes = (2 * n, task_rows * n, task_rows, task_rows, n * n, n, rows * n, 2 * (n + rows), 2 * boxes * n)
    ends = np.cumsum(np.array(sizes))
    starts = ends - np.array(sizes)
    return (
        data[starts[0]:ends[0]].reshape(2, n), data[starts[1]:ends[1]].reshape(task_rows, n),
        data[starts[2]:ends[2]], data[starts[3]:ends[3]], data[starts[4]:ends[4]].reshape(n, n),
        data[starts[5]:ends[5]], data[starts[6]:ends[6]].reshape(rows, n),
        data[starts[7]:ends[7]].reshape(2, n + rows), data[starts[8]:ends[8]].reshape(2 * boxes, n),
    )


class CyclePlan:
    """The compiled plan of one controller's tasks and constraints (module docstring); ``of``
    gives None when one of them has no kernel of the plan (one of ``kinds``)."""

    kinds = KERNEL_KINDS

    def __init__(self, objects: list, table: np.ndarray, impacts: list, buffers: CycleBuffers, dt: float, first_relaxed: int):
        self.objects, self.table, self.impacts, self.buffers, self.dt = objects, table, impacts, buffers, dt
        self.first_relaxed = first_relaxed  # the first relaxed row of C
        n = buffers.problem.H.shape[0]
        self.parameters = np.empty(HEAD)
        self._edits = (-1, -1)  # the parameter edits of the last packing
        edges = impacts[0].friction.count if impacts else 0
        # impact i's [A, P, G] (3 n^2, ``impact_cycle_kernels.fixed_base_matrix_views``), its edges' A_i, P_i
        # (2 x edges x n x n) and its activation, in row i
        self.impacts_data = np.zeros((max(len(impacts), 1), (3 + 2 * edges) * n * n + 1))
        self._impact_rows = [(row[:3 * n * n], row[3 * n * n:-1].reshape(2, edges, n, n)) for row in self.impacts_data]
        # Whether the kernel updates the impacts itself (``ExpectedImpact.plan_updates_it``)
        self.updates_impacts = bool(impacts) and all(impact.plan_updates_it for impact in impacts)

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
        if n < 3 or len({impact.friction.count for impact in impacts}) > 1:  # the stacks' shapes (``__init__``)
            return None
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
        """The objects' ``kernel_parameters`` into the packed array (after its ``HEAD``) and their
        offsets into the table."""
        packed = [
            item.kernel_parameters(self.dt) if isinstance(item, PositionLimit) else item.kernel_parameters()
            for item in self.objects
        ]
        sizes = np.array([len(values) for values in packed], dtype=np.int64)
        self.table[:, PARAMETERS] = HEAD + np.cumsum(sizes) - sizes
        rules = [impact.plan_values() for impact in self.impacts] if self.updates_impacts else []
        self.parameters = np.concatenate([np.zeros(HEAD), *packed, *rules])  # the impacts' rule values last
        b = self.buffers
        head = (self.first_relaxed, b.task_A.shape[0], b.problem.C.shape[0], b.box_bounds.shape[0] // 2, len(rules))
        self.parameters[FIRST_RELAXED:HEAD] = head
        self._edits = (Task.parameter_edits, Constraint.parameter_edits, ExpectedImpact.rule_edits)

    def _impact_maps(self, terms: ModelTerms) -> np.ndarray:
        """The kernels' ``impacts`` at ``terms`` (zeros when there is none): row i holds the
        expected impact i's [A, P, G], its edges' A_i and P_i, written by the impact
        (``ExpectedImpact.fill_stacked``), and its activation (1 or 0), last."""
        data = self.impacts_data
        for i, impact in enumerate(self.impacts):
            maps, edges = self._impact_rows[i]
            data[i, -1] = impact.fill_stacked(terms, maps, edges)
        return data

    def fill(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Every task and constraint row of this state into the buffers (one compiled call, which
        also updates the expected impacts when it can update them all: ``updates_impacts``); False when
        the box bounds conflict."""
        parameters, data, locked = self._cycle_parameters(cycle), self.buffers.data, terms.locked_body
        if not self.updates_impacts:
            impacts = self._impact_maps(terms)
            return planned_rows(terms.arm_state, terms.M, terms.h, impacts, self.table, parameters, data, locked)
        impacts = self.impacts_data
        consistent = planned_rows(terms.arm_state, terms.M, terms.h, impacts, self.table, parameters, data, locked)
        for impact, (maps, edges), row in zip(self.impacts, self._impact_rows, impacts):
            impact.adopt_stacked(terms, row[-1] != 0.0, maps, edges)
        return consistent

    def _cycle_parameters(self, cycle: ControlCycle) -> np.ndarray:
        """The packed parameters (packed again when a task's or a constraint's attribute was
        assigned since) with this cycle's horizon and dt in their head, its reachable
        accelerations in the buffers (where the controller's ``ControlCycle`` already keeps them)."""
        if self._edits != (Task.parameter_edits, Constraint.parameter_edits, ExpectedImpact.rule_edits):
            self.pack()
        parameters, b = self.parameters, self.buffers
        parameters[HORIZON], parameters[DT] = cycle.horizon, cycle.dt
        if cycle.acceleration_lower is not b.reachable_lower or cycle.acceleration_upper is not b.reachable_upper:
            b.reachable_lower[:], b.reachable_upper[:] = cycle.acceleration_lower, cycle.acceleration_upper
        return parameters


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
def planned_rows(state, M, h, impacts, table, parameters, data, locked):
    """Kernel of ``CyclePlan.fill``, of flat arrays only (numba types a tuple argument element
    by element at every call): ``state`` = the arm's [J6, (J J^T)^-1, p, dJ6 dq, dq, R, q]
    (``model_terms.arm_state_views``), M, h; ``impacts`` = the expected impacts' rows
    (``CyclePlan._impact_maps``); ``parameters`` = [h, dt, the first relaxed row, the task rows,
    the general rows, the boxes, the number of impacts the kernel updates, the lines' parameters,
    those impacts' ``plan_values``]; ``data`` = the reachable accelerations,
    the task rows A, b, w, the QP H, g, C, [[lb; l], [ub; u]] and the box bounds
    (``cycle_buffer_views``); ``locked`` = the locked robot's [centre of mass, inertia, mass]
    (``ModelTerms.locked_body``), read when the kernel updates the impacts first
    (``stacked_updates``). Each line of ``table`` runs its class's kernel on its slice with its
    parameters (the layouts of the classes' ``kernel_parameters``); then H = A^T W A,
    g = -A^T W b, the boxes intersected into [lb, ub] within the reachable interval, and the
    rows from the first relaxed one on relaxed to what [lb, ub] reaches. False when the boxes
    conflict."""
    n = M.shape[0]
    J6, _, _, dJ6_dq, dq, rotation, q = arm_state_views(state, n)
    sizes = int(parameters[TASK_ROWS]), int(parameters[GENERAL_ROWS]), int(parameters[BOXES])
    reachable, task_A, task_b, task_w, H, g, C, bounds, box_bounds = cycle_buffer_views(data, n, *sizes)
    lower, upper = bounds[0], bounds[1]
    first_relaxed = int(parameters[FIRST_RELAXED])
    rules = int(parameters[RULES])
    if rules:  # each impact's rule values and its edges' directions
        size = RULE_VALUES + 3 * (((impacts.shape[1] - 1) // (n * n) - 3) // 2)
        rule_values = parameters[parameters.shape[0] - rules * size:].reshape((rules, size))
        stacked_updates(state[:6 * n + CONTACT_TERMS_EXTRA], dq, locked, M, rule_values, impacts)
    inputs = (q, dq, J6, dJ6_dq, rotation, M, h)
    cycle = (reachable[0], reachable[1], parameters[HORIZON], parameters[DT])
    planned_task_rows(inputs, table, parameters, (task_A, task_b, task_w))
    weighted_least_squares(task_A, task_b, task_w, single_entry_columns(table, sizes[0], n), H, g)
    consistent = planned_boxes(inputs, cycle, table, parameters, box_bounds, lower, upper)
    planned_general_rows(inputs, impacts, parameters[HORIZON], table, parameters, (H, g, box_bounds, lower, upper, C))
    relax_to_reachable(C[first_relaxed:], lower[n + first_relaxed:], upper[n + first_relaxed:], lower[:n], upper[:n])
    return consistent


@njit(cache=True)
def single_entry_columns(table, task_rows, n):
    """Kernel: for each of the ``task_rows`` stacked task rows of ``table``, the column of its one
    entry when it is a posture row (A = [0 I], the last rows of n velocities) or a damping row
    (A = I), else -1 (``weighted_least_squares``' ``columns``)."""
    columns = np.full(task_rows, -1, dtype=np.int64)
    for e in range(table.shape[0]):
        kind, first, rows = table[e, KIND], table[e, FIRST], table[e, ROWS]
        if kind == POSTURE or kind == DAMPING:
            offset = n - rows if kind == POSTURE else 0
            for j in range(rows):
                columns[first + j] = offset + j
    return columns


@njit(cache=True)
def planned_task_rows(state, table, parameters, task_rows):
    """Kernel: the rows of the approach, posture and damping tasks of ``table`` (the other lines
    left as they are), for ``state`` = (q, dq, J6, dJ6 dq, R, M, h) and ``task_rows`` = (A, b, w)."""
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
    of ``table``, for ``planned_task_rows``' ``state``, ``impacts`` (``planned_rows``': row i
    = [A, P, G (in n^2 values), the edges' A_i and P_i, the activation]), ``horizon`` h and
    ``qp`` = (H, g, the box bounds, [lb; l], [ub; u], C)."""
    dq, M, h = state[1], state[5], state[6]
    C, lower, upper = qp[5], qp[3], qp[4]
    n = dq.shape[0]
    square = n * n
    edges = ((impacts.shape[1] - 1) // square - 3) // 2  # (3 + 2 edges) n^2 + 1 values a row
    inv_h = 1.0 / horizon
    for e in range(table.shape[0]):
        kind, first, rows, p, i = table[e, KIND], table[e, FIRST], table[e, ROWS], table[e, PARAMETERS], table[e, IMPACT]
        last = first + rows
        if kind == TORQUE:
            normalised_torque_rows(M, h, parameters[p:p + rows], C[first:last], lower[n + first:n + last], upper[n + first:n + last])
            continue
        if kind != POST_IMPACT and kind != IMPULSIVE:
            continue
        row = impacts[i]
        edge_maps = row[3 * square:3 * square + 2 * edges * square].reshape(2, edges, n, n)
        active = row[row.shape[0] - 1] != 0.0
        if kind == POST_IMPACT:  # a block of rows per map: A, then each edge's A_i
            edge_post_impact_velocity_rows(
                (row[:square].reshape(n, n), edge_maps[0]), dq, parameters[p:p + rows // (1 + edges)], inv_h, active,
                C[first:last], lower[n + first:n + last], upper[n + first:n + last],
            )
        else:  # P, then each edge's P_i
            edge_scaled_impulse_rows(
                (row[square:2 * square].reshape(n, n), edge_maps[1]), parameters[p:p + 2 * n].reshape((2, n)), dq, inv_h,
                active, C[first:last], lower[n + first:n + last], upper[n + first:n + last],
            )
