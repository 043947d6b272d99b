"""Impact-aware whole-body QP controller of the kinematic-controlled standing G1
(docs/whole-body-qp.md).

One control cycle, as the arm's ``ImpactAwareController``::

    state (q, v) -> model terms (one ``RobotModel.update_terms`` call into the cycle's buffer) -> task rows and constraint
    rows -> QP in dv (nv: base and joint accelerations) -> Command(dv, v_cmd = v + dv dt,
    q_cmd = q (+) (v + v_cmd) dt / 2)

The QP reuses the arm's machinery: the preallocated ``QpProblem`` and ``ConstraintLayout``
(boxes intersected, general rows stacked, relaxed rows last), the same solvers with an
independent second solver confirming any failure, and the arm's compiled kernels for the cost
H = A^T W A, g = -A^T W b (which skips the zero entries of the posture and damping rows), the
box intersection and the active set. The acceleration and jerk
limits of the actuated joints always apply (``AccelerationLimit`` is added when missing); the
base's accelerations get a generous box (``BASE_ACCELERATION_LIMIT``, no jerk limit): the
feet's equality rows (``HeldContactRows``) set them.

Fallback: when the state is unusable (wrong size, non-finite, a joint past its velocity limit),
the QP is infeasible or no solver succeeds, the actuated joints brake within their acceleration
and jerk limits (the arm's braking kernel, dv_b with zero base acceleration), then dv_b is
projected onto the feet's rows by the least-norm change, dv = dv_b - Jf^T (Jf Jf^T)^-1
(Jf dv_b + dJf v): the feet take precedence over the joints' acceleration limits in a fallback
(both feet over-determine the base); the status says why. An unusable
state is replaced by the previous command (BadInputError when there is none yet).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from impactqp.constraints import Constraint, ControlCycle, ExpectedImpact
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.robot import BASE_ACCELERATION_LIMIT, RobotModel
from impactqp.tasks import Task

from .command import Command, CommandMemory, Status, command_limits
from .controller import checked_constraints, first_outside, intersect_boxes, tight_constraints, weighted_least_squares
from .fallback import bounded_conflict, braking_command
from .problem import ConstraintLayout, QpProblem, consecutive_slices
from .solvers import FAILED, INFEASIBLE, SOLVED, make_solver, verifier_for


class WholeBodyController:
    """Whole-body QP with impact-aware constraints (``step(q, v) -> Command``) for the G1.

    ``tasks`` must make the cost strictly convex over the nv accelerations (a
    ``DampingTask(variables=nv)`` does); ``impact`` is the expected impact whose jump fills
    ``Command.predicted_jump`` (None: no prediction).
    """

    def __init__(
        self,
        robot: RobotModel,
        tasks: list[Task],
        constraints: list[Constraint],
        dt: float,
        solver: str = "daqp",
        impact: ExpectedImpact | None = None,
        feasibility_tolerance: float = 1e-6,
    ):
        constraints = checked_constraints(tasks, constraints, dt)
        self.robot, self.tasks, self.constraints = robot, list(tasks), constraints
        self.layout = ConstraintLayout.of(constraints)
        self.dt = float(dt)
        self.impact = impact
        self.feasibility_tolerance = float(feasibility_tolerance)
        n = robot.nv
        self.solver = make_solver(solver, self.layout.rows, n)
        self.verifier = verifier_for(self.solver.name, self.layout.rows, n)
        self.fallback_count = 0
        self.memory = CommandMemory(None, np.zeros(n), np.zeros(n))
        self._targets_set = False
        self._allocate()

    def _allocate(self) -> None:
        """The buffers of one cycle and the views each task and constraint writes into."""
        robot, layout, n = self.robot, self.layout, self.robot.nv
        slices = consecutive_slices([t.rows for t in self.tasks])
        rows = sum(t.rows for t in self.tasks)
        self._task_A, self._task_b, self._task_w = np.zeros((rows, n)), np.zeros(rows), np.zeros(rows)
        self._task_views = [(t, self._task_A[s], self._task_b[s], self._task_w[s]) for t, s in zip(self.tasks, slices)]
        self.problem = p = QpProblem.empty(layout.rows, n)
        self._box_bounds = layout.empty_box_bounds(n)
        self._box_lower, self._box_upper = self._box_bounds[0::2], self._box_bounds[1::2]
        self._row_views = [(c, p.C[s], p.l[s], p.u[s]) for c, s in zip(layout.row_constraints, layout.row_slices)]
        first = layout.first_relaxed_row
        self._relaxed_rows = (p.C[first:], p.l[first:], p.u[first:])
        self._active_flags = layout.empty_flags()
        self.ddq_max = np.concatenate([np.full(robot.base_nv, BASE_ACCELERATION_LIMIT), robot.ddq_max])
        self._jerk_step = np.concatenate([np.full(robot.base_nv, np.inf), robot.dddq_max * self.dt])
        self._joint_coordinates = slice(robot.base_nq, None)  # the actuated joints' part of q
        self._joint_velocities = slice(robot.base_nv, None)  # and of v
        self._joint_limits = command_limits(robot, robot.ddq_max, robot.dddq_max * self.dt)
        horizon = max(self.dt, float(np.max(robot.ddq_max / robot.dddq_max)))
        self._cycle = ControlCycle(self.dt, np.zeros(n), np.zeros(n), horizon)
        self._terms = robot.empty_terms()
        self._row_cycle = ControlCycle(self.dt, p.lb, p.ub, horizon)

    def reset(self, q, v=None) -> None:
        """Re-initialise the command memory at (q, v) (zero acceleration) and re-capture the
        task targets left unspecified."""
        terms = self.robot.terms(q, v)
        self.memory = CommandMemory(terms.q.copy(), terms.dq.copy(), np.zeros(self.robot.nv))
        for task in self.tasks:
            task.reset(terms)
        self._targets_set = True

    def step(self, q, v) -> Command:
        """One control cycle (module docstring); never raises once a command was issued."""
        try:
            terms = self.robot.update_terms(self._terms, q, v)
        except (BadInputError, TypeError, ValueError) as error:
            return self._fallback(None, Status.FALLBACK_INVALID_STATE, [], str(error))
        joints = self._joint_velocities
        over = first_outside(terms.dq[joints], self.robot.dq_max)
        if over >= 0:
            message = f"joint {over} velocity {terms.dq[joints][over]:.4f} rad/s is outside the velocity limits"
            return self._fallback(terms, Status.FALLBACK_INVALID_STATE, ["joint_velocity_limit"], message)
        if not self._targets_set:
            for task in self.tasks:
                task.reset(terms)
            self._targets_set = True
        self._cycle.advance(self.memory.ddq, self.ddq_max, self._jerk_step)
        if not self.assemble(terms):
            return self._infeasible(terms, "the joint-space bounds conflict")
        solved, dv, solver_name = self._solve()
        if solved == INFEASIBLE:
            return self._infeasible(terms, f"the QP is infeasible (confirmed by {solver_name})")
        if solved != SOLVED:
            return self._fallback(terms, Status.FALLBACK_SOLVER_ERROR, [], "no solver found a solution")
        v_cmd = terms.dq + dv * self.dt
        joint_command = v_cmd[joints]
        status = Status.OK
        if first_outside(joint_command, self.robot.dq_max) >= 0:
            np.clip(joint_command, -self.robot.dq_max, self.robot.dq_max, out=joint_command)
            dv = (v_cmd - terms.dq) / self.dt
            status = Status.VELOCITY_CLIPPED
            self.problem.violation(dv)
        return self._emit(terms, dv, v_cmd, status, self._active_constraints(dv), [], solver_name)

    def assemble(self, terms: ModelTerms) -> bool:
        """Fill the QP from the tasks and constraints of this state (the arm's ``_assemble``);
        False when the box bounds conflict."""
        for task, A, b, w in self._task_views:
            task.compute_into(terms, A, b)
            w[:] = task.weight
        weighted_least_squares(self._task_A, self._task_b, self._task_w, self.problem.H, self.problem.g)
        problem, cycle = self.problem, self._cycle
        for k, constraint in enumerate(self.layout.box_constraints):
            constraint.compute_into(terms, cycle, None, self._box_lower[k], self._box_upper[k])
        consistent = intersect_boxes(
            self._box_lower, self._box_upper, cycle.acceleration_lower, cycle.acceleration_upper, problem.lb, problem.ub
        )
        for constraint, C, lower, upper in self._row_views:
            constraint.compute_into(terms, self._row_cycle, C, lower, upper)
        self._row_cycle.recoverable(*self._relaxed_rows)
        return consistent

    def _solve(self) -> tuple[str, np.ndarray | None, str]:
        """The chosen solver, then the verifier on any failure or inaccurate answer."""
        for solver in (self.solver, self.verifier):
            try:
                solved, x = solver.solve(self.problem)
            except Exception:  # a backend error must not stop the control loop
                solved, x = FAILED, None
            if solved == SOLVED and self.problem.violation(x) > self.feasibility_tolerance:
                solved, x = FAILED, None
            if solved == SOLVED:
                return solved, x, solver.name
        return solved, None, self.verifier.name

    def _active_constraints(self, dv: np.ndarray) -> list[str]:
        flags, p = self._active_flags, self.problem
        tolerance = 10.0 * self.feasibility_tolerance
        tight_constraints(dv, self._box_bounds, p.lower_gap, p.upper_gap, self.layout.row_ends, tolerance, flags)
        return [name for name, hit in zip(self.layout.flag_names, flags) if hit]

    def _infeasible(self, terms: ModelTerms, message: str) -> Command:
        conflict = bounded_conflict(self.layout, self.problem, self._box_bounds, self._active_flags)
        return self._fallback(terms, Status.FALLBACK_INFEASIBLE, conflict, f"{message}; conflict: {', '.join(conflict)}")

    def _fallback(self, terms: ModelTerms | None, status: Status, violated, message: str) -> Command:
        """Joints brake, the base follows the feet (module docstring)."""
        self.fallback_count += 1
        if terms is None:
            if self.memory.q_cmd is None:
                raise BadInputError(f"no command yet to stand in for an unusable state: {message}")
            terms = self.robot.terms(self.memory.q_cmd, self.memory.dq_cmd)
        n, joints = self.robot.nv, self._joint_velocities
        dv, v_cmd, q_joints = np.zeros(n), np.empty(n), np.empty(self.robot.n_joints)
        braking_command(
            terms.q[self._joint_coordinates], terms.dq[joints], self.memory.ddq[joints], self.dt, self._joint_limits,
            dv[joints], v_cmd[joints], q_joints,
        )
        Jf = terms.held_jacobian
        dv -= Jf.T @ np.linalg.solve(Jf @ Jf.T, Jf @ dv + terms.held_drift)
        v_cmd = terms.dq + dv * self.dt
        np.clip(v_cmd[joints], -self.robot.dq_max, self.robot.dq_max, out=v_cmd[joints])
        return self._emit(terms, dv, v_cmd, status, [], list(violated), "", message)

    def _emit(self, terms, dv, v_cmd, status, active, violated, solver, message="") -> Command:
        """q_cmd = q (+) (v + v_cmd) dt / 2, joints within their limits; the memory; the Command
        with the jump the expected impact predicts at v_cmd."""
        q_cmd = pin.integrate(self.robot.model, terms.q, 0.5 * self.dt * (terms.dq + v_cmd))
        joints = self._joint_coordinates
        q_cmd[joints] = np.clip(q_cmd[joints], self.robot.q_min, self.robot.q_max)
        self.memory = CommandMemory(q_cmd, v_cmd, dv)
        if self.impact is not None:
            jump = self.impact.matrices(terms).jump_matrix @ v_cmd
            active_impact = self.impact.is_active(terms)
        else:
            jump, active_impact = np.zeros(self.robot.nv), False
        return Command(dv, v_cmd, q_cmd, status, active, violated, jump, v_cmd + jump, active_impact, solver, message)
