"""Impact-aware task-space QP controller of a kinematic-controlled robot, fixed or floating base.

One control cycle, straight through::

    state (q, dq) -> model terms (one ``robot.update_terms`` call) -> task rows and constraint rows
    -> QP in ddq -> Command(ddq, dq_cmd = dq + ddq dt, q_cmd = q (+) (dq + dq_cmd) dt / 2)

The QP (``problem``) is in the generalized acceleration ddq (nv values: a floating base's
``base_nv`` base accelerations first, then the actuated joints'): the tasks' weighted least
squares under the box and general constraints, every row in acceleration units
(``constraints.constraint``). The acceleration and jerk limits between consecutive commands
always apply to the actuated joints (``AccelerationLimit`` is added when missing); a floating
base's accelerations get a generous box (``BASE_ACCELERATION_LIMIT``, no jerk limit): the held
contacts' equality rows (``HeldContactRows``) set them. (+) is Pinocchio's ``integrate`` on a
floating base (the base's quaternion), the plain sum on a fixed base.

Solving (``solvers``): a solution is accepted only when it is finite and satisfies every row to
``feasibility_tolerance`` (acceleration units). A second, independent solver confirms any failed
or inaccurate solve before the QP is declared infeasible, so the controller never brakes on
one solver's false alarm (docs/qp-constraints.md, Solvers).

Cycle time: everything a cycle touches is allocated once (the terms refilled in place, each task
and constraint writing into its own buffers, the QP data in two stacked bound vectors [box; rows]
read without copies); the jump matrices are computed once per cycle (``ExpectedImpact.matrices``).
When every task and constraint has a kernel of a compiled cycle plan (``cycle_plan``, ``whole_body_plan``),
one compiled call writes all their rows, else they are written object by object (``_assemble``).
On a fixed base on daqp, the solve, the solution's check and the command are one more compiled
call (``solved_command``); what it cannot accept takes the path below.

Fallback (``fallback``): when the state is unusable (non-finite, outside the position or
velocity limits, singular contact Jacobian), when the QP is infeasible, or when no solver
succeeds, the command is a joint-wise brake within the acceleration and jerk limits; on a
floating base the brake ddq_b (zero base acceleration) is then projected onto the held
contacts' rows by the least-norm change ddq = ddq_b - Jf^T (Jf Jf^T)^-1 (Jf ddq_b + dJf dq), so
the held contacts take precedence over the joints' acceleration limits. The status says why,
``violated_constraints`` names the conflicting or violated constraints and ``fallback_count``
counts fallbacks. A fallback never returns a NaN and never raises, except on a floating base
whose very first state is unusable (``BadInputError``: nothing can stand in for the base's pose).
For an infeasible QP, ``step`` stays bounded: it names the conflicting set of one compiled
interval test; the irreducible conflicting set is computed only on demand, after the fact, by
``conflicting_constraints()``, from the rows stored by the last infeasible cycle.

Impact brake: a fixed-base controller fed the measured state notices an impact itself (a floating
base's soft standing servo lags its commands too much for this rule while it accelerates: its
session detects the impact, ``controller.runtime.session``). While its expected
impact's rows were active at the previous cycle, the contact point's measured speed towards the
surface, -n.(J dq), falls below ``IMPACT_SPEED_DROP`` times the speed the previous command asks
there, -n.(J dq_cmd) (the predicted jump takes it to -c_r times itself; a servo's tracking error
is far smaller). From then on the controller brakes its own command trajectory to rest within
the acceleration and jerk limits, from the previous command (q_cmd, dq_cmd, ddq) and not from the
measured state: after an impact that pushed a joint past its velocity limit, braking from the
measured state would command the limit itself for as long as the lagging servo keeps the joint
above it. Then it holds the rest it reached; status ``impact_brake``, phase ``brake``, until
``reset``. A loop fed its own previous command sees no jump and never brakes (``ImpactSession``
detects the impact from the joint torques and switches controllers).

Velocity limit: the velocity limit on dq_cmd is a row of the QP (``VelocityLimit``, at the
jerk horizon), so in a closed loop the QP's answer needs no clipping. When the measured state
makes clipping unavoidable (dq_cmd past its limit), dq_cmd is clipped, ``ddq`` is set to
(dq_cmd - dq) / dt so that the command stays consistent, and the status is
``ok_velocity_clipped``. (A fallback from a state already outside the velocity limits cannot
keep both: it keeps ddq within the acceleration and jerk limits and clips dq_cmd; its status
says it is a fallback.)
"""

from __future__ import annotations

import numpy as np

from impactqp.constraints import AccelerationLimit, Constraint, ControlCycle, ExpectedImpact
from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.robot import BASE_ACCELERATION_LIMIT, InvalidStateError, RobotModel, SingularPostureError
from impactqp.controller.model.validation import BadInputError
from impactqp.tasks import Task

from .command import Command, CommandMemory, Status, command_limits
from .cycle_plan import CycleBuffers
from .cycle_kernels import COMMAND_ROWS, checked_solution, first_outside, integrate_command, intersect_boxes
from .cycle_kernels import weighted_least_squares
from .elastic_relaxation import ElasticRelaxation
from .fallback import bounded_conflict, brake, irreducible_conflict, usable_state
from .floating_command import floating_command, held_brake
from .held_elimination import held_elimination
from .problem import ConstraintLayout, QpProblem, consecutive_slices
from .solved_command import SolvedCommand
from .solvers import FAILED, INFEASIBLE, SOLVED, DaqpSolver, make_solver, verifier_for
from .whole_body_plan import compiled_plan

BRAKE = "brake"
ACTIVE_PATTERNS = 256  # patterns of the active constraints' flags whose names are kept


class ImpactAwareController:
    """Task-space QP controller with impact-aware constraints (``step(q, dq) -> Command``).

    Parameters
    ----------
    robot : RobotModel, a fixed base or a floating base (its held contacts' rows come from the
        constraints: ``HeldContactRows``).
    tasks : least-squares tasks (``tasks``); at least one, and together they must make the
        cost strictly convex (a ``DampingTask`` does).
    constraints : constraints (``constraints``); an ``AccelerationLimit`` is added when missing.
    dt : control period (s).
    solver : "daqp" (default), "proxqp", or any qpsolvers backend name.
    impact : the expected impact used for ``Command.predicted_jump`` (None: no prediction).
    feasibility_tolerance : largest accepted row violation of a solution (acceleration units).
    joint_limits : (ddq_max, dddq_max) of the actuated joints (default: the robot's
        description's). ``ddq_max`` and ``dddq_max`` of the controller cover every
        velocity (a floating base's box first).
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
        joint_limits: tuple[np.ndarray, np.ndarray] | None = None,
    ):
        constraints = checked_constraints(tasks, constraints, dt)
        self.robot = robot
        self.tasks = list(tasks)
        self.constraints = constraints
        self.layout = ConstraintLayout.of(constraints)
        self.dt = float(dt)
        joint_ddq_max, joint_dddq_max = (
            (robot.ddq_max, robot.dddq_max) if joint_limits is None else (np.asarray(j, float) for j in joint_limits)
        )
        base = robot.base_nv
        self._floating = base > 0
        self._joint_velocities = slice(base, None)  # and of dq
        self.ddq_max = np.concatenate([np.full(base, BASE_ACCELERATION_LIMIT), joint_ddq_max])
        self.dddq_max = np.concatenate([np.full(base, np.inf), joint_dddq_max])
        self.impact = impact
        self.feasibility_tolerance = float(feasibility_tolerance)
        self._allocate()
        self.solver = held_elimination(make_solver(solver, self.layout.rows, robot.nv), self.layout, robot)
        self.verifier = verifier_for(self.solver.name, self.layout.rows, robot.nv)
        self._solved_command = None if self._floating or not isinstance(self.solver, DaqpSolver) else SolvedCommand(
            self.solver, self._buffers, self.layout.row_ends, self._active_flags, self._limits
        )
        self.fallback_count = 0
        self.memory = CommandMemory(None, np.zeros(robot.nv), np.zeros(robot.nv))
        self._targets_set = False
        self._last_infeasible: tuple[QpProblem, np.ndarray, np.ndarray] | None = None
        self.phase = "approach"
        self._impact_was_active = False  # at the previous cycle
        self.braking = False

    def _allocate(self) -> None:
        """The buffers of one cycle and the views each task and constraint writes into."""
        layout, n = self.layout, self.robot.nv
        task_slices = consecutive_slices([t.rows for t in self.tasks])
        n_task_rows = sum(t.rows for t in self.tasks)
        buffers = CycleBuffers.empty(n, n_task_rows, layout.rows, len(layout.box_constraints))
        self._task_A, self._task_b, self._task_w = buffers.task_A, buffers.task_b, buffers.task_w
        self._gathered = np.full(n_task_rows, -1, dtype=np.int64)  # every task row's columns gathered
        self._task_views = [
            (task, self._task_A[s], self._task_b[s], self._task_w[s]) for task, s in zip(self.tasks, task_slices)
        ]
        self._active_flags = layout.empty_flags()
        self._active_names: dict[bytes, list[str]] = {}  # the names of each pattern of the flags seen
        self._buffers, self.problem = buffers, buffers.problem
        p = self.problem
        self._box_bounds = buffers.box_bounds  # rows 2k and 2k + 1: the bounds of box k
        self._box_lower, self._box_upper = self._box_bounds[0::2], self._box_bounds[1::2]
        self._row_views = [(c, p.C[s], p.l[s], p.u[s]) for c, s in zip(layout.row_constraints, layout.row_slices)]
        first = layout.first_relaxed_row
        self._relaxed_rows = (p.C[first:], p.l[first:], p.u[first:])
        self._terms = self.robot.empty_terms()  # refilled in place every cycle
        self._jerk_step = self.dddq_max * self.dt
        self._no_jump = np.zeros((n, n))  # the jump matrix without an expected impact
        joints = self._joint_velocities
        self._limits = command_limits(self.robot, self.ddq_max[joints], self._jerk_step[joints])
        horizon = max(self.dt, float(np.max(self.ddq_max / self.dddq_max)))
        self._cycle = ControlCycle(self.dt, buffers.reachable_lower, buffers.reachable_upper, horizon)
        # General rows see the joint-space box of the cycle (all box constraints intersected)
        # as the reachable accelerations, so that a row the state violates is relaxed to what
        # the box really allows (ControlCycle.recoverable): the arrays are the problem's own.
        self._row_cycle = ControlCycle(self.dt, p.lb, p.ub, horizon)
        self._plan = compiled_plan(self.tasks, layout, buffers, self.dt)  # None: the generic assembly
        # a floating base's relaxed rows, widened within its held contacts' rows when the QP is infeasible
        self._elastic = ElasticRelaxation(layout.rows, first, n) if self._floating and first < layout.rows else None

    @property
    def box_constraints(self) -> tuple[Constraint, ...]:
        return self.layout.box_constraints

    @property
    def row_constraints(self) -> tuple[Constraint, ...]:
        """The general constraints in the order of their rows (the relaxed ones last)."""
        return self.layout.row_constraints

    def conflicting_constraints(self) -> list[str]:
        """The irreducible conflicting set of the last infeasible cycle (deletion filter with
        daqp, computed now, off the control cycle); [] when no cycle was infeasible."""
        if self._last_infeasible is None:
            return []
        return irreducible_conflict(self.layout, [c.name for c in self.constraints], *self._last_infeasible)

    # ------------------------------------------------------------------ public API
    def reset(self, q, dq=None) -> None:
        """Re-initialise the command memory at the state (q, dq) (zero acceleration) and
        re-capture the task targets left unspecified."""
        terms = self.robot.terms(q, dq, check_limits=False)
        self.memory = CommandMemory(terms.q.copy(), terms.dq.copy(), np.zeros(self.robot.nv))
        self.braking, self._impact_was_active = False, False
        if self.phase == BRAKE:
            self.phase = "approach"
        for task in self.tasks:
            task.reset(terms)
        self._targets_set = True

    def step(self, q: np.ndarray, dq: np.ndarray) -> Command:
        """One control cycle from the state (q, dq): the measured state, or the previous command
        (q_cmd, dq_cmd) of a kinematic-controlled robot; the Command to send (its ``dq_cmd``, or
        its ``q_cmd``). Never raises on a bad state or a solver failure (module docstring:
        fallback), except on a floating base whose first state is unusable; after a noticed
        impact it brakes to rest (module docstring: impact brake)."""
        if self.braking:
            return self._impact_brake()
        robot = self.robot
        try:
            robot.update_terms(self._terms, q, dq)
        except InvalidStateError as error:
            return self._fallback(q, dq, Status.FALLBACK_INVALID_STATE, [error.constraint], str(error))
        except SingularPostureError as error:
            return self._fallback(q, dq, Status.FALLBACK_SINGULAR, [], str(error))
        except (BadInputError, TypeError, ValueError) as error:  # not a state of this robot
            return self._fallback(q, dq, Status.FALLBACK_INVALID_STATE, ["finite_state"], str(error))
        terms = self._terms
        if self._impact_was_active and not self._floating and self._impact_noticed(terms, dq):
            self.braking = True
            return self._impact_brake()
        joint_velocities = terms.dq[self._joint_velocities] if self._floating else terms.dq
        over = first_outside(joint_velocities, robot.dq_max)
        if over >= 0:
            message = f"dq{over + 1} = {joint_velocities[over]:.4f} rad/s is outside the velocity limits"
            return self._fallback(q, dq, Status.FALLBACK_INVALID_STATE, ["joint_velocity_limit"], message, terms)
        if not self._targets_set:
            for task in self.tasks:
                task.reset(terms)
            self._targets_set = True

        self._cycle.advance(self.memory.ddq, self.ddq_max, self._jerk_step)
        if not self._assemble(terms, self._cycle):
            return self._infeasible(q, dq, terms, "the joint-space bounds conflict")

        # dq_cmd = dq + ddq dt (clipped only off the closed loop: see the docstring) and
        # q_cmd = q (+) (dq + dq_cmd) dt / 2 within the position limits
        # one compiled pass: dq_cmd, q_cmd (on a floating base's manifold), the predicted jump and post-impact velocity
        jump_matrix = self._no_jump if self.impact is None else self.impact.row_matrices(terms).jump_matrix
        answer = None  # daqp's, when the compiled end of the cycle could not accept it
        if self._solved_command is not None:  # a fixed base on daqp: solve, check and command in one call
            accepted, answer = self._solved_command.run(terms, jump_matrix, self.dt, self.feasibility_tolerance)
            if accepted is not None:
                return self._commanded(terms, *accepted, self.solver.name)
        solved, ddq, solver_name = self._solve(answer)
        if solved == INFEASIBLE and self._elastic is not None and self._elastic.widen(self.problem):
            solved, ddq, solver_name = self._solve()  # the relaxed rows widened within the held contacts' rows
        if solved == INFEASIBLE:
            return self._infeasible(q, dq, terms, f"the QP is infeasible (confirmed by {solver_name})")
        if solved != SOLVED:
            return self._fallback(q, dq, Status.FALLBACK_SOLVER_ERROR, [], "no solver found a solution", terms)
        if self._floating:
            *command, clipped = floating_command(robot.model, terms, ddq, self.dt, self._limits, jump_matrix)
        else:
            command = np.empty((COMMAND_ROWS, robot.nv))
            clipped = integrate_command(terms.q, terms.dq, ddq, self.dt, self._limits, jump_matrix, command)
        return self._commanded(terms, ddq, command, clipped, solver_name)

    # ------------------------------------------------------------------ one cycle
    def _commanded(self, terms: ModelTerms, ddq: np.ndarray, command, clipped: bool, solver_name: str) -> Command:
        """The Command of a solved cycle: ddq and the command's rows (dq_cmd, q_cmd, the jump, the
        post-impact velocity), ddq made consistent with a clipped dq_cmd."""
        status = Status.OK
        if clipped:
            ddq = (command[0] - terms.dq) * (1.0 / self.dt)
            status = Status.VELOCITY_CLIPPED
            self._checked(ddq)  # the gaps and the active constraints of the ddq actually commanded
        motion = (ddq, command[0], command[1], command[2], command[3])
        return self._emit(terms, motion, status, self._active_constraints(), [], solver_name)

    def _impact_noticed(self, terms: ModelTerms, dq: np.ndarray) -> bool:
        """Whether this state shows an impact (module docstring: impact brake); a state that is the
        previous command itself (``dq``, the step's argument, is the previous dq_cmd: a loop fed its
        own command) never does."""
        impact, memory = self.impact, self.memory
        if impact is None or memory.q_cmd is None or dq is memory.sent_dq_cmd:
            return False
        return impact.shows_jump(terms.J, terms.dq, memory.dq_cmd)

    def _impact_brake(self) -> Command:
        """The brake of the command trajectory from the previous command, to rest, then rest."""
        memory = self.memory
        self.phase = BRAKE
        if self._floating:
            terms = self.robot.terms(memory.q_cmd, memory.dq_cmd, check_limits=False)
            ddq, dq_cmd, q_cmd = held_brake(self.robot, terms, memory.ddq, self.dt, self._limits)
        else:
            ddq, dq_cmd, q_cmd = brake(memory.q_cmd, memory.dq_cmd, memory.ddq, self.dt, self._limits)
        return self._emit(None, (ddq, dq_cmd, q_cmd), Status.IMPACT_BRAKE, [], [], "", "braking after a noticed impact")

    def _assemble(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Fill the preallocated QP data from the tasks and constraints of this state, in one
        compiled call when every one has a kernel (``cycle_plan``), else object by object; False
        when the joint-space bounds conflict (lb > ub somewhere)."""
        if self._plan is not None:
            return self._plan.fill(terms, cycle)
        self._assemble_tasks(terms)
        return self._assemble_constraints(terms, cycle)

    def _assemble_tasks(self, terms: ModelTerms) -> None:
        """Cost: H = A^T W A and g = -A^T W b over the stacked rows of every task."""
        for task, A, b, w in self._task_views:
            task.compute_into(terms, A, b)
            w[:] = task.weight
        weighted_least_squares(self._task_A, self._task_b, self._task_w, self._gathered, self.problem.H, self.problem.g)

    def _assemble_constraints(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Bounds: the box constraints intersected and clipped into the cycle's reachable
        accelerations, then the general rows, the relaxed ones relaxed in one block. False when
        the box bounds conflict."""
        problem = self.problem
        box_lower, box_upper = self._box_lower, self._box_upper
        for k, constraint in enumerate(self.layout.box_constraints):
            constraint.compute_into(terms, cycle, None, box_lower[k], box_upper[k])
        # Clipping each box into the reachable interval, then intersecting, equals intersecting
        # then clipping (clipping is monotone): two vectors are clipped instead of every box.
        consistent = intersect_boxes(
            box_lower, box_upper, cycle.acceleration_lower, cycle.acceleration_upper, problem.lb, problem.ub
        )
        row_cycle = self._row_cycle  # its bounds are problem.lb and problem.ub, filled above
        for constraint, C, lower, upper in self._row_views:
            constraint.compute_into(terms, row_cycle, C, lower, upper)
        row_cycle.recoverable(*self._relaxed_rows)
        return consistent

    def _solve(self, answer: tuple | None = None) -> tuple[str, np.ndarray | None, str]:
        """Solve with the chosen solver (its ``answer`` (status, x) when already had); a second
        solver confirms any failure or inaccurate answer. Returns (status, ddq, name of the
        solver whose answer counts)."""
        problem = self.problem
        try:
            solved, x = self.solver.solve(problem) if answer is None else answer
        except Exception:  # a backend error must not stop the control loop
            solved, x = FAILED, None
        if solved == SOLVED and self._checked(x) <= self.feasibility_tolerance:  # finite, every row and bound met
            return SOLVED, x, self.solver.name
        try:
            solved, x = self.verifier.solve(problem)
        except Exception:
            solved, x = FAILED, None
        if solved == SOLVED and not self._checked(x) <= self.feasibility_tolerance:
            solved, x = FAILED, None
        return solved, x, self.verifier.name

    def _checked(self, x: np.ndarray) -> float:
        """The largest violation of a row or bound by x, and in the same compiled call the active
        constraints' flags of x (a row within 10 x ``feasibility_tolerance`` of a bound)."""
        p, tolerance = self.problem, self.feasibility_tolerance * 10.0
        return checked_solution(p.C, x, p.bounds, p.gaps, self._box_bounds, self.layout.row_ends, tolerance, self._active_flags)

    def _active_constraints(self) -> list[str]:
        """Names of the constraints with at least one row at a bound at the commanded ddq (the
        flags of its check, ``_checked``: when it was accepted, or clipped)."""
        key = self._active_flags.tobytes()  # a few patterns recur along a loop: their lists are kept
        names = self._active_names.get(key)
        if names is None:
            if len(self._active_names) >= ACTIVE_PATTERNS:
                self._active_names.clear()
            names = self._active_names[key] = [n for n, hit in zip(self.layout.flag_names, self._active_flags.tolist()) if hit]
        return names.copy()

    # ------------------------------------------------------------------ fallback
    def _infeasible(self, q, dq, terms, message) -> Command:
        self._last_infeasible = (self.problem.copy(), self._box_lower.copy(), self._box_upper.copy())
        conflict = bounded_conflict(self.layout, self.problem, self._box_bounds, self._active_flags)
        return self._fallback(
            q, dq, Status.FALLBACK_INFEASIBLE, conflict, f"{message}; conflict: {', '.join(conflict)}", terms
        )

    def _fallback(self, q, dq, status, violated, message, terms: ModelTerms | None = None) -> Command:
        """Joint-wise braking within the acceleration and jerk limits (``fallback``); on a
        floating base, projected onto the held contacts' rows (module docstring)."""
        self.fallback_count += 1
        if self._floating:
            terms = terms if terms is not None else self._stand_in_terms(q, dq, message)
            ddq, dq_cmd, q_cmd = held_brake(self.robot, terms, self.memory.ddq, self.dt, self._limits)
        else:
            q, dq = usable_state(q, dq, self.memory, self.robot)
            ddq, dq_cmd, q_cmd = brake(q, dq, self.memory.ddq, self.dt, self._limits)
        return self._emit(terms, (ddq, dq_cmd, q_cmd), status, [], list(violated), "", message)

    def _stand_in_terms(self, q, dq, message: str) -> ModelTerms:
        """The terms of an unusable floating-base state: the state itself when it has the right
        sizes and finite values (only a limit broken), else the previous command; BadInputError
        when there is none yet (nothing can stand in for the base's pose)."""
        try:
            return self.robot.terms(q, dq, check_limits=False)
        except (BadInputError, TypeError, ValueError):
            pass
        if self.memory.q_cmd is None:
            raise BadInputError(f"no command yet to stand in for an unusable state: {message}")
        return self.robot.terms(self.memory.q_cmd, self.memory.dq_cmd, check_limits=False)

    def _emit(self, terms, motion, status, active, violated, solver, message="") -> Command:
        """Record the command ``motion`` = (ddq, dq_cmd, q_cmd[, jump, post-impact velocity]) in the
        memory and package it with the impact prediction at dq_cmd (computed here when ``motion``
        does not bring it, from the matrices of this cycle)."""
        ddq, dq_cmd, q_cmd, *prediction = motion
        memory = self.memory
        memory.q_cmd, memory.dq_cmd, memory.ddq = q_cmd.copy(), dq_cmd.copy(), ddq.copy()
        memory.sent_dq_cmd = dq_cmd
        predicts = self.impact is not None and terms is not None
        if not prediction:
            jump = np.zeros(self.robot.nv)
            try:
                if predicts:
                    jump = self.impact.matrices(terms).jump_matrix @ dq_cmd
            except SingularPostureError as error:  # a fallback's state where the jump has no prediction
                predicts, message = False, f"{message}; no jump prediction: {error}"
            prediction = (jump, dq_cmd + jump)
        self._impact_was_active = impact_active = predicts and self.impact.is_active(terms)
        return Command(
            ddq, dq_cmd, q_cmd, status, active, violated, *prediction, impact_active, solver, message, self.phase
        )


def checked_constraints(tasks: list[Task], constraints: list[Constraint], dt: float) -> list[Constraint]:
    """The constraints of a controller, an ``AccelerationLimit`` first when missing; BadInputError
    without a task, for dt <= 0 or for two constraints of one name."""
    if not tasks:
        raise BadInputError("the controller needs at least one task")
    if not dt > 0.0:
        raise BadInputError("dt must be > 0")
    constraints = list(constraints)
    if not any(isinstance(c, AccelerationLimit) for c in constraints):
        constraints.insert(0, AccelerationLimit())
    names = [c.name for c in constraints]
    if len(set(names)) != len(names):
        raise BadInputError(f"constraint names must be unique, got {names}")
    return constraints
