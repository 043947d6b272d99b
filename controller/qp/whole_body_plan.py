"""The compiled cycle plan of a whole-body QP: the arm's plan (``cycle_plan``) with the kernels of
a standing robot's tasks and constraints, every row of one cycle in ONE compiled call.

``WholeBodyPlan`` serves a controller whose tasks and constraints are all among
``WHOLE_BODY_KINDS`` (exactly these classes), at least one of them not among the arm's
``KERNEL_KINDS`` (those keep the arm's plan, whose call reads fewer arrays): the centre-of-mass
and frame tasks, the held contacts' equality rows, the capture region and the feet's wrenches at
the impact (frictionless: the edge variants keep the generic assembly). Its table and packed
parameters are the arm plan's (a frame task's line holds its index among the frame tasks in the
column of the expected impact); ``fill`` passes the frame tasks' frames (position, rotation, J6,
dJ6 v: ``FrameTask.frame_state``) stacked (a floating base's buffer's own stacked frame arrays,
else copies), the expected impacts' maps (A, P, the edges', G,
C and the held contacts' impulse map Z, computed once with the jump maps) and activations, and
calls ``whole_body_rows``: the arm plan's kernels on their lines, each class's own kernel on its
lines (``com_rows``, ``frame_rows``, ``capture_rows``, ``foot_wrench_rows``; the held contacts'
rows C = Jf, l = u = -dJf v), then the cost, the boxes and the relaxed rows as
``cycle_plan.planned_rows``. The QP it writes is the generic assembly's: the same kernels on the
same inputs. The model terms a line does not need are not read (a floating base's h, and M
unless a torque limit asks for it, stay unfilled; the rows read M^-1 only through the impacts'
maps).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.constraints import CaptureRegionLimit, ControlCycle, FootWrenchLimit, HeldContactRows
from impactqp.constraints.capture_constraint import capture_rows
from impactqp.constraints.constraint import relax_to_reachable
from impactqp.constraints.foot_wrench import foot_wrench_rows
from impactqp.controller.model.capture import GRAVITY
from impactqp.controller.model.model_terms import ModelTerms
from impactqp.tasks import CentreOfMassTask, FrameTask
from impactqp.tasks.com_task import com_rows
from impactqp.tasks.frame_task import FRAME_PARAMETERS, frame_rows

from .cycle_kernels import weighted_least_squares
from .cycle_plan import (
    BOXES, DT, FIRST, FIRST_RELAXED, GENERAL_ROWS, HORIZON, IMPACT, KERNEL_KINDS, KIND, PARAMETERS, ROWS, TASK_ROWS,
    TORQUE, CyclePlan, cycle_buffer_views, planned_boxes, planned_general_rows, planned_task_rows, single_entry_columns,
)

COM, FRAME = 4, 5
HELD, CAPTURE, FOOT_WRENCH = 23, 24, 25
WHOLE_BODY_KINDS = {
    **KERNEL_KINDS, CentreOfMassTask: COM, FrameTask: FRAME,
    HeldContactRows: HELD, CaptureRegionLimit: CAPTURE, FootWrenchLimit: FOOT_WRENCH,
}
"""The classes with a kernel of the whole-body plan (exactly these classes)."""
FRAME_OFFSET = 14  # the frame task's weights in its parameters, after kp, kd, p* and R*
BODY_KINDS = (COM, CAPTURE, FOOT_WRENCH)  # the lines that read Jcom, dJcom v and the centre of mass


def compiled_plan(tasks, layout, buffers, dt) -> CyclePlan | None:
    """The compiled plan of a controller's ``tasks`` and of the constraints of ``layout``: the
    arm's (``CyclePlan``) when it has a kernel for every one, else the whole-body plan when it
    has, else None (the generic assembly)."""
    plan = CyclePlan.of(tasks, layout, buffers, dt)
    return plan if plan is not None else WholeBodyPlan.of(tasks, layout, buffers, dt)


class WholeBodyPlan(CyclePlan):
    """The compiled plan of a whole-body controller's tasks and constraints (module docstring);
    ``of`` gives None when one of them has no kernel of this plan, or when the arm's plan has
    one for every one of them."""

    kinds = WHOLE_BODY_KINDS

    @classmethod
    def of(cls, tasks, layout, buffers, dt) -> WholeBodyPlan | None:
        objects = [*tasks, *layout.box_constraints, *layout.row_constraints]
        if all(type(item) in KERNEL_KINDS for item in objects):
            return None
        plan = super().of(tasks, layout, buffers, dt)
        if plan is None:
            return None
        frame_tasks = [task for task in tasks if type(task) is FrameTask]
        for f, task in enumerate(frame_tasks):
            plan.table[tasks.index(task), IMPACT] = f
        n, count = buffers.problem.H.shape[0], max(len(frame_tasks), 1)
        plan.frame_tasks = frame_tasks
        plan.frames = (
            np.zeros((count, 3)), np.zeros((count, 3, 3)), np.zeros((count, 6, n)), np.zeros((count, 6)), np.arange(count),
        )
        plan.stacked = (None, None, np.arange(count))
        kinds = set(plan.table[:, KIND].tolist())
        plan.reads = (TORQUE in kinds, bool(kinds & set(BODY_KINDS)))
        plan.placeholders = (
            np.zeros((n, n)), np.zeros(n), np.zeros((3, n)), np.zeros(3), np.zeros((3, 3)), np.zeros((0, 3)),
        )
        return plan

    def fill(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Every task and constraint row of this state into the buffers (one compiled call);
        False when the box bounds conflict."""
        parameters = self._cycle_parameters(cycle)
        maps = self._impact_maps(terms)
        body_maps = self._body_maps(terms)
        frames = self._frames(terms)
        square, vector, Jcom, point = self.placeholders[:4]
        torque, body = self.reads
        state = (terms.q, terms.dq, terms.J6, terms.dJ6_dq, terms.contact_rotation,
                 terms.M if torque else square, terms.h if torque else vector)
        body_terms = (
            terms.Jcom if body else Jcom, terms.dJcom_dq if body else point, terms.com if body else point,
            terms.held_jacobian, terms.held_drift, terms.mass,
        )
        return whole_body_rows((state, body_terms, frames), (maps, body_maps), self.table, parameters, self.buffers.data)

    def _frames(self, terms: ModelTerms) -> tuple:
        """The frame tasks' frames as the rows' kernel reads them, (p, R, J6, dJ6 v, index): a
        floating base's stacked frame arrays (``ModelTerms.frame_arrays``: its contact frame,
        held contacts, then named frames), task f's frame at ``index[f]`` of them (found once
        per buffer and frame names); else each task's ``frame_state`` copied into the plan's own
        arrays, task f's at f."""
        stacked = terms.frame_arrays
        if stacked is None:
            positions, rotations, jacobians, drifts, _ = self.frames
            for f, task in enumerate(self.frame_tasks):
                positions[f], rotations[f], jacobians[f], drifts[f] = task.frame_state(terms)
            return self.frames
        source, names, index = self.stacked
        tasks_frames = [task.frame for task in self.frame_tasks]
        if source is not stacked or names != tasks_frames:
            for task in self.frame_tasks:
                task.frame_state(terms)  # raises for a frame the robot does not name
            named = list(terms.body.frames)
            first = len(stacked[0]) - len(named)  # the named frames follow the contact and held ones
            index = np.array([0 if name is None else first + named.index(name) for name in tasks_frames] or [0])
            self.stacked = stacked, tasks_frames, index
        J6, drifts, positions, rotations = stacked
        return positions, rotations, J6, drifts, index

    def _body_maps(self, terms: ModelTerms) -> tuple[tuple, tuple, tuple]:
        """Each expected impact's centre-of-mass map C, impulse map G and held contacts' impulse
        map Z (without held contacts: zeros, and Z of no rows)."""
        zeros, no_rows = self.placeholders[4], self.placeholders[5]
        if not self.impacts:
            return (zeros,), (zeros,), (no_rows,)
        com_maps, impulse_maps, held_maps = [], [], []
        for impact in self.impacts:
            matrices = impact.row_matrices(terms)
            com_maps.append(zeros if matrices.com_map is None else matrices.com_map)
            impulse_maps.append(matrices.impulse_map)
            held_maps.append(impact.held_impulse_map(terms))
        return tuple(com_maps), tuple(impulse_maps), tuple(held_maps)


@njit(cache=True)
def whole_body_rows(inputs, maps, table, parameters, data):
    """Kernel of ``WholeBodyPlan.fill``: ``cycle_plan.planned_rows`` with the lines of the
    whole-body kinds, for inputs = (``planned_rows``' state, body, frames), body = (Jcom, dJcom v,
    c, Jf, dJf v, m), frames = the frames' stacked (p, R, J6, dJ6 v, index) (``_frames``), maps =
    (``planned_rows``' impacts, (each impact's C, G and Z)), and ``table``, ``parameters`` and
    ``data`` (the controller's buffers, ``cycle_buffer_views``) as ``planned_rows``'."""
    state, body, frames = inputs
    impacts, body_maps = maps
    n = state[1].shape[0]
    sizes = int(parameters[TASK_ROWS]), int(parameters[GENERAL_ROWS]), int(parameters[BOXES])
    reachable, task_A, task_b, task_w, H, g, C, bounds, box_bounds = cycle_buffer_views(data, n, *sizes)
    lower, upper = bounds[0], bounds[1]
    first_relaxed, horizon = int(parameters[FIRST_RELAXED]), parameters[HORIZON]
    task_rows, qp = (task_A, task_b, task_w), (H, g, box_bounds, lower, upper, C)
    planned_task_rows(state, table, parameters, task_rows)
    body_task_rows(state[1], body, frames, table, parameters, task_rows)
    weighted_least_squares(task_A, task_b, task_w, single_entry_columns(table, sizes[0], n), H, g)
    consistent = planned_boxes(state, (reachable[0], reachable[1], horizon, parameters[DT]), table, parameters, box_bounds, lower, upper)
    planned_general_rows(state, impacts, horizon, table, parameters, qp)
    body_general_rows((state[1], state[2], body), body_maps, impacts[:, -1], horizon, table, parameters, qp)
    relax_to_reachable(C[first_relaxed:], lower[n + first_relaxed:], upper[n + first_relaxed:], lower[:n], upper[:n])
    return consistent


@njit(cache=True)
def body_task_rows(dq, body, frames, table, parameters, task_rows):
    """Kernel: the rows of the centre-of-mass and frame tasks of ``table`` (parameters: kp, kd,
    the target, the weights; a frame task's line holds its index f, its frame is at
    ``index[f]`` of ``frames`` = (p, R, J6, dJ6 v, index))."""
    Jcom, dJcom_dq, com = body[0], body[1], body[2]
    positions, rotations, jacobians, drifts, index = frames
    task_A, task_b, task_w = task_rows
    for e in range(table.shape[0]):
        kind, first, rows, p, f = table[e, KIND], table[e, FIRST], table[e, ROWS], table[e, PARAMETERS], table[e, IMPACT]
        last = first + rows
        if kind == COM:
            gains = (parameters[p], parameters[p + 1])
            com_rows(Jcom, dq, com, dJcom_dq, parameters[p + 2:p + 5], gains, task_A[first:last], task_b[first:last])
            task_w[first:last] = parameters[p + 5:p + 8]
        elif kind == FRAME:
            k = index[f]
            frame = (positions[k], rotations[k], jacobians[k], drifts[k])
            frame_rows(frame, dq, parameters[p:p + FRAME_OFFSET], task_A[first:last], task_b[first:last])
            task_w[first:last] = parameters[p + FRAME_OFFSET:p + FRAME_PARAMETERS]


@njit(cache=True)
def body_general_rows(state, body_maps, active, horizon, table, parameters, qp):
    """Kernel: the held contacts' rows (C = Jf, l = u = -dJf v), the capture region's and the
    feet's wrench rows of ``table`` (unbounded while their impact is not active), for
    ``state`` = (v, J6, ``whole_body_rows``'s body)."""
    dq, J6, body = state
    Jcom, com, Jf, drift, mass = body[0], body[2], body[3], body[4], body[5]
    com_maps, impulse_maps, held_maps = body_maps
    C, row_lower, row_upper = qp[5], qp[3][dq.shape[0]:], qp[4][dq.shape[0]:]  # the general rows' bounds
    inv_h = 1.0 / horizon
    for e in range(table.shape[0]):
        kind, p, i = table[e, KIND], table[e, PARAMETERS], table[e, IMPACT]
        rows = table[e, ROWS]
        span = slice(table[e, FIRST], table[e, FIRST] + rows)
        rows_C, rows_lower, rows_upper = C[span], row_lower[span], row_upper[span]
        if kind == HELD:
            rows_C[:] = Jf
            rows_lower[:] = -drift
            rows_upper[:] = rows_lower
            continue
        if kind != CAPTURE and kind != FOOT_WRENCH:
            continue
        rows_lower[:] = -np.inf
        if not active[i]:
            rows_C[:] = 0.0
            rows_upper[:] = np.inf
        elif kind == CAPTURE:
            normals = parameters[p + 1:p + 1 + 2 * rows].reshape((rows, 2))
            offsets = parameters[p + 1 + 2 * rows:p + 1 + 3 * rows]
            omega = np.sqrt(GRAVITY / (com[2] - parameters[p]))
            capture_rows(
                (Jcom, J6, com_maps[i], impulse_maps[i]), (com, dq), (normals, offsets), (omega, inv_h), rows_C, rows_upper
            )
        else:
            feet = int(parameters[p])
            edges = rows // feet - 1
            start = p + 2 + feet
            rotations = parameters[start:start + 9 * feet].reshape((feet, 3, 3))
            start += 9 * feet
            standing = parameters[start:start + 36 * feet].reshape((6 * feet, 6))
            start += 36 * feet
            soles = parameters[start:start + 6 * feet * edges].reshape((feet, edges, 6))
            foot_wrench_rows(
                (held_maps[i], np.ascontiguousarray(J6[:3]), impulse_maps[i]), (dq, com, mass),
                (rotations, standing, soles, parameters[p + 2:p + 2 + feet]), (parameters[p + 1], inv_h),
                rows_C, rows_upper,
            )
