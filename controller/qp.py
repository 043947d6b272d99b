"""Impact-aware task-space QP controller of a kinematic-controlled Panda.

One control cycle, straight through::

    state (q, dq) -> model terms (one ``robot.terms`` call) -> task rows and constraint rows
    -> QP in ddq -> Command(ddq, dq_cmd = dq + ddq dt, q_cmd = q + dq dt + ddq dt^2 / 2)

The QP (decision variable ddq, the joint acceleration)::

    minimize    sum_tasks sum_i w_i (A_i ddq - b_i)^2
    subject to  lb <= ddq <= ub                     (box constraints, intersected)
                l  <= C ddq <= u                    (general constraints)

with every row in acceleration units (``constraints.constraint``). The acceleration and jerk
limits between consecutive commands always apply (``AccelerationLimit`` is added when missing).

Solvers
-------
``solver="daqp"`` (default): daqp (dual active set) called directly on the preallocated data.
``solver="proxqp"``: proxsuite dense, initialised once and then updated and warm-started every
cycle. Any other name is solved through ``qpsolvers.solve_problem(..., solver=name)``;
``"qpsolvers:proxqp"`` forces proxqp through qpsolvers. The choice of the default is measured in
the README (solver table). A solution is accepted only when it is finite and satisfies every
row to ``feasibility_tolerance`` (acceleration units). A second, independent solver confirms any
failed or inaccurate solve before the QP is declared infeasible (quadprog, Goldfarb-Idnani, for
daqp; daqp for every other backend), so the controller never brakes on one solver's false alarm
(warm-started proxsuite 0.8 reports some feasible QPs as infeasible: docs/qp-constraints.md).

Cycle time
----------
Everything a cycle touches is allocated once: the model terms are refilled in place
(``PandaModel.update_terms``), the control cycle is advanced in place, tasks and constraints
write into their own buffers, and the QP data live in two stacked bound vectors
[box; rows] that the solver and the feasibility check read without copies. The jump maps are
computed once per cycle (``ImpactModel.maps``) and shared by the impact constraints and the
Command's prediction.

Fallback (safe command)
-----------------------
When the state is unusable (non-finite, outside the position or velocity limits, singular
contact Jacobian), when the QP is infeasible, or when no solver succeeds, the command is a
joint-wise brake within the acceleration and jerk limits::

    ddq = clip(-dq / dt, reachable accelerations of the cycle)     (ControlCycle)
    dq_cmd = clip(dq + ddq dt, -dq_max, dq_max),  q_cmd = clip(q + dq dt + ddq dt^2/2, q_min, q_max)

For a non-finite state the previous command stands in for (q, dq) (or, before any command, the
finite entries of q with zero velocity, mid-range for non-finite entries). The status says
why, ``violated_constraints`` names the conflicting or violated constraints and
``fallback_count`` counts fallbacks. A fallback never raises and never returns a NaN.

For an infeasible QP, ``step`` stays bounded: ``violated_constraints`` is a conflicting set
found with one compiled interval test (the general constraints whose rows cannot be met
anywhere in the joint-space box, plus the box constraints that shape that box; when no single
general constraint conflicts with the box, every constraint with rows). The irreducible
conflicting set (a deletion filter: one daqp solve per constraint) is computed only on demand,
after the fact, by ``conflicting_constraints()``, from the rows stored by the last infeasible
cycle.

Velocity limit
--------------
The velocity limit on dq_cmd is a row of the QP (``VelocityLimit``, at the jerk horizon), so in
a closed loop the QP's answer needs no clipping. When the measured state makes clipping
unavoidable (dq_cmd past its limit), dq_cmd is clipped, ``ddq`` is set to (dq_cmd - dq) / dt so
that the command stays consistent, and the status is ``ok_velocity_clipped``. (A fallback from
a state already outside the velocity limits cannot keep both: it keeps ddq within the
acceleration and jerk limits and clips dq_cmd; its status says it is a fallback.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import daqp
import numpy as np
import proxsuite
import quadprog
from numba import njit

from impactqp.constraints import AccelerationLimit, Constraint, ControlCycle, ImpactModel
from impactqp.tasks import Task

from .model.robot import NQ, InvalidStateError, ModelTerms, PandaModel, SingularPostureError
from .model.validation import BadInputError, all_finite

STATUS_OK = "ok"
STATUS_VELOCITY_CLIPPED = "ok_velocity_clipped"
STATUS_FALLBACK_INFEASIBLE = "fallback_infeasible"
STATUS_FALLBACK_INVALID_STATE = "fallback_invalid_state"
STATUS_FALLBACK_SINGULAR = "fallback_singular_posture"
STATUS_FALLBACK_SOLVER_ERROR = "fallback_solver_error"

SOLVED, INFEASIBLE, FAILED = "solved", "infeasible", "failed"
_PROXQP_INFINITY = 1e20


class Command:
    """The output of one control cycle for a kinematic-controlled robot.

    ``predicted_jump`` is the joint-velocity jump an impact would cause at the commanded
    velocity (dq- = dq_cmd) with the controller's prediction model, and
    ``predicted_post_impact_velocity`` = dq_cmd + predicted_jump; both are zero when the
    controller has no impact model or the state was unusable. ``phase`` is the phase of the
    impact session that issued the command (``docs/robot-loop.md``). A plain slotted class:
    one is made per cycle, so it must cost little.
    """

    __slots__ = (
        "ddq", "dq_cmd", "q_cmd", "status", "active_constraints", "violated_constraints", "predicted_jump",
        "predicted_post_impact_velocity", "impact_constraints_active", "solver", "message", "phase",
    )

    def __init__(
        self, ddq, dq_cmd, q_cmd, status, active_constraints, violated_constraints, predicted_jump,
        predicted_post_impact_velocity, impact_constraints_active=False, solver="", message="", phase="approach",
    ):
        self.ddq = ddq
        self.dq_cmd = dq_cmd
        self.q_cmd = q_cmd
        self.status = status
        self.active_constraints = active_constraints
        self.violated_constraints = violated_constraints
        self.predicted_jump = predicted_jump
        self.predicted_post_impact_velocity = predicted_post_impact_velocity
        self.impact_constraints_active = impact_constraints_active
        self.solver = solver
        self.message = message
        self.phase = phase

    @property
    def is_fallback(self) -> bool:
        return self.status not in (STATUS_OK, STATUS_VELOCITY_CLIPPED)

    def __repr__(self) -> str:
        return f"Command(status={self.status!r}, phase={self.phase!r}, dq_cmd={self.dq_cmd!r})"


class QpProblem:
    """Preallocated QP data: cost 1/2 x^T H x + g^T x, box lb <= x <= ub, rows l <= C x <= u.

    The bounds live in two stacked vectors ``lower`` = [lb; l] and ``upper`` = [ub; u] (lb, l,
    ub and u are views of them), the layout daqp reads directly; infinite entries are unbounded.
    """

    def __init__(self, H, g, C, l, u, lb, ub):
        rows = C.shape[0]
        self.H, self.g, self.C = H, g, C
        self.lower, self.upper = np.concatenate([lb, l]), np.concatenate([ub, u])
        self.lb, self.l = self.lower[:NQ], self.lower[NQ:]
        self.ub, self.u = self.upper[:NQ], self.upper[NQ:]
        self._stacked = np.zeros(NQ + rows)  # [x; C x]
        self.lower_gap = np.zeros(NQ + rows)  # [x; C x] - lower, of the last ``violation``
        self.upper_gap = np.zeros(NQ + rows)  # upper - [x; C x]

    @classmethod
    def empty(cls, rows: int) -> QpProblem:
        return cls(np.zeros((NQ, NQ)), np.zeros(NQ), np.zeros((rows, NQ)), np.zeros(rows), np.zeros(rows),
                   np.zeros(NQ), np.zeros(NQ))

    def copy(self) -> QpProblem:
        return QpProblem(self.H.copy(), self.g.copy(), self.C.copy(), self.l, self.u, self.lb, self.ub)

    def stacked(self, x: np.ndarray) -> np.ndarray:
        """[x; C x] in a preallocated vector (valid until the next call)."""
        z = self._stacked
        z[:NQ] = x
        np.matmul(self.C, x, out=z[NQ:])
        return z

    def violation(self, x: np.ndarray) -> float:
        """Largest violation of a bound or row by x (0 when x is feasible, inf when x is not
        finite); the gaps to the bounds stay in ``lower_gap`` and ``upper_gap``."""
        return stacked_violation(self.C, x, self.lower, self.upper, self.lower_gap, self.upper_gap)

    def reference_violation(self, x: np.ndarray) -> float:
        """``violation`` in plain numpy (the reference of its kernel)."""
        if not np.isfinite(x).all():
            return np.inf
        z = self.stacked(x)
        below = np.subtract(z, self.lower, out=self.lower_gap).min()
        above = np.subtract(self.upper, z, out=self.upper_gap).min()
        return max(-below, -above, 0.0)


class ProxqpDenseSolver:
    """proxsuite dense QP, initialised once and then updated and warm-started every cycle."""

    name = "proxqp"

    def __init__(self, rows: int, tolerance: float = 1e-7, max_iterations: int = 200):
        self.qp = proxsuite.proxqp.dense.QP(NQ, 0, rows, True)
        settings = self.qp.settings
        settings.max_iter = max_iterations  # bounded cycle time; a second solver confirms any failure
        settings.max_iter_in = max_iterations
        settings.eps_abs = tolerance
        settings.eps_rel = 0.0
        # Primal and dual residuals alone accept a warm start whose multipliers sit on bounds
        # that are no longer active (only the bounds moved): the duality gap catches that.
        settings.check_duality_gap = True
        settings.eps_duality_gap_abs = tolerance
        settings.eps_duality_gap_rel = 0.0
        settings.verbose = False
        settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
        self.initialized = False
        self._l = np.zeros(rows)
        self._u = np.zeros(rows)

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        l = np.maximum(problem.l, -_PROXQP_INFINITY, out=self._l)
        u = np.minimum(problem.u, _PROXQP_INFINITY, out=self._u)
        if self.initialized:
            self.qp.update(problem.H, problem.g, None, None, problem.C, l, u, problem.lb, problem.ub)
        else:
            self.qp.init(problem.H, problem.g, None, None, problem.C, l, u, problem.lb, problem.ub)
            self.initialized = True
        self.qp.solve()
        status = self.qp.results.info.status
        if status == proxsuite.proxqp.PROXQP_SOLVED:
            return SOLVED, self.qp.results.x.copy()
        self.initialized = False  # start the next cycle from a fresh init
        if status == proxsuite.proxqp.PROXQP_PRIMAL_INFEASIBLE:
            return INFEASIBLE, None
        return FAILED, None


class DaqpSolver:
    """daqp called directly on the stacked bounds [lb; l] <= [x; C x] <= [ub; u]."""

    name = "daqp"

    def __init__(self, rows: int):
        self._sense = np.zeros(NQ + rows, dtype=np.int32)

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        sense = self._sense
        sense.fill(0)  # daqp writes the working set into it
        x, _, exitflag, _ = daqp.solve(problem.H, problem.g, problem.C, problem.upper, problem.lower, sense)
        if exitflag >= 1:
            return SOLVED, x
        return (INFEASIBLE if exitflag == -1 else FAILED), None


class QuadprogSolver:
    """quadprog (Goldfarb-Idnani dual active set), the independent second opinion for daqp.

    It solves min 1/2 x^T H x - a^T x s.t. A^T x >= b, so every finite bound becomes one
    inequality. quadprog reports an infeasible problem only by a ValueError whose text says the
    constraints are inconsistent; any other error is a failure.
    """

    name = "quadprog"

    def __init__(self, rows: int):
        del rows  # quadprog takes the problem as it comes

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        upper, lower = np.isfinite(problem.upper), np.isfinite(problem.lower)
        identity_and_rows = np.vstack([np.eye(NQ), problem.C])
        A = np.vstack([-identity_and_rows[upper], identity_and_rows[lower]])
        b = np.concatenate([-problem.upper[upper], problem.lower[lower]])
        try:
            x = quadprog.solve_qp(problem.H, -problem.g, A.T, b, 0)[0]
        except ValueError as error:
            return (INFEASIBLE if "inconsistent" in str(error) else FAILED), None
        return SOLVED, x


class QpsolversSolver:
    """Any backend of ``qpsolvers`` (one-shot: no warm start); l <= C x <= u becomes
    [C; -C] x <= [u; -l] without the unbounded rows."""

    def __init__(self, backend: str):
        import qpsolvers

        if backend not in qpsolvers.available_solvers:
            raise BadInputError(
                f"QP solver {backend!r} is not available; available: "
                f"daqp (direct), proxqp (direct, warm-started), "
                f"{', '.join(qpsolvers.available_solvers)} (through qpsolvers)"
            )
        self.backend = backend
        self.name = f"qpsolvers:{backend}"

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        import qpsolvers

        G = np.vstack([problem.C, -problem.C])
        h = np.concatenate([problem.u, -problem.l])
        finite = np.isfinite(h)
        solution = qpsolvers.solve_problem(
            qpsolvers.Problem(problem.H, problem.g, G[finite], h[finite], lb=problem.lb, ub=problem.ub),
            solver=self.backend,
        )
        if solution.found and solution.x is not None and np.all(np.isfinite(solution.x)):
            return SOLVED, np.asarray(solution.x, dtype=float)
        return FAILED, None


def available_backends() -> list[str]:
    """Every solver name ``make_solver`` accepts on this machine."""
    import qpsolvers

    return ["daqp", "proxqp"] + [f"qpsolvers:{name}" for name in qpsolvers.available_solvers]


def make_solver(name: str, rows: int):
    """The QP backend called ``name`` (see the module docstring)."""
    if name == "proxqp":
        return ProxqpDenseSolver(rows)
    if name == "daqp":
        return DaqpSolver(rows)
    return QpsolversSolver(name.removeprefix("qpsolvers:"))


@dataclass
class CommandMemory:
    """The previous command, for continuity (jerk limits) and for unusable states."""

    q_cmd: np.ndarray | None = None
    dq_cmd: np.ndarray = field(default_factory=lambda: np.zeros(NQ))
    ddq: np.ndarray = field(default_factory=lambda: np.zeros(NQ))


class ImpactAwareController:
    """Task-space QP controller with impact-aware constraints (``step(q, dq) -> Command``).

    Parameters
    ----------
    robot : PandaModel
    tasks : least-squares tasks (``tasks``); at least one, and together they must make the
        cost strictly convex (a ``DampingTask`` does).
    constraints : constraints (``constraints``); an ``AccelerationLimit`` is added when missing.
    dt : control period (s).
    solver : "daqp" (default), "proxqp", or any qpsolvers backend name.
    impact : the impact model used for ``Command.predicted_jump`` (None: no prediction).
    feasibility_tolerance : largest accepted row violation of a solution (acceleration units).
    acceleration_limit, jerk_limit : ddq_max and dddq_max (default: the robot's datasheet values).
    """

    def __init__(
        self,
        robot: PandaModel,
        tasks: list[Task],
        constraints: list[Constraint],
        dt: float,
        solver: str = "daqp",
        impact: ImpactModel | None = None,
        feasibility_tolerance: float = 1e-6,
        acceleration_limit: np.ndarray | None = None,
        jerk_limit: np.ndarray | None = None,
    ):
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
        self.robot = robot
        self.tasks = list(tasks)
        self.constraints = constraints
        self.box_constraints = [c for c in constraints if c.is_box]
        # Relaxed rows last, in one block that ControlCycle.recoverable relaxes at once.
        self.row_constraints = sorted((c for c in constraints if not c.is_box), key=lambda c: c.relaxed)
        self.dt = float(dt)
        self.ddq_max = robot.ddq_max if acceleration_limit is None else np.asarray(acceleration_limit, float)
        self.dddq_max = robot.dddq_max if jerk_limit is None else np.asarray(jerk_limit, float)
        self.impact = impact
        self.feasibility_tolerance = float(feasibility_tolerance)

        self._task_slices = _consecutive_slices([t.rows for t in self.tasks])
        n_task_rows = sum(t.rows for t in self.tasks)
        self._task_A = np.zeros((n_task_rows, NQ))
        self._task_b = np.zeros(n_task_rows)
        self._task_w = np.zeros((n_task_rows, 1))
        self._row_slices = _consecutive_slices([c.rows for c in self.row_constraints])
        self._row_starts = np.array([s.start for s in self._row_slices], dtype=int)
        self._row_ends = np.array([s.stop for s in self._row_slices], dtype=np.int64)
        self._flag_names = [c.name for c in self.box_constraints] + [c.name for c in self.row_constraints]
        self._active_flags = np.zeros(len(self._flag_names), dtype=np.bool_)
        self.problem = QpProblem.empty(sum(c.rows for c in self.row_constraints))
        # Box bounds interleaved: rows 2k and 2k+1 are the lower and upper bounds of box k.
        self._box_bounds = np.zeros((2 * len(self.box_constraints), NQ))
        self._box_lower = self._box_bounds[0::2]
        self._box_upper = self._box_bounds[1::2]
        first_relaxed = sum(c.rows for c in self.row_constraints if not c.relaxed)
        p = self.problem
        self._task_views = [(task, self._task_A[s], self._task_b[s], self._task_w[s, 0]) for task, s in zip(self.tasks, self._task_slices)]
        self._row_views = [(c, p.C[s], p.l[s], p.u[s]) for c, s in zip(self.row_constraints, self._row_slices)]
        self._relaxed_rows = (p.C[first_relaxed:], p.l[first_relaxed:], p.u[first_relaxed:])

        rows = self.problem.C.shape[0]
        self.solver = make_solver(solver, rows)
        self.verifier = QuadprogSolver(rows) if self.solver.name == "daqp" else DaqpSolver(rows)
        self.fallback_count = 0
        self.memory = CommandMemory()
        self._targets_set = False
        self._last_infeasible: tuple[QpProblem, np.ndarray, np.ndarray] | None = None
        self.phase = "approach"

        self._terms: ModelTerms | None = None  # refilled in place every cycle
        self._jerk_step = self.dddq_max * self.dt
        horizon = max(self.dt, float(np.max(self.ddq_max / self.dddq_max)))
        self._cycle = ControlCycle(self.dt, np.zeros(NQ), np.zeros(NQ), horizon)
        # General rows see the joint-space box of the cycle (all box constraints intersected)
        # as the reachable accelerations, so that a row the state violates is relaxed to what
        # the box really allows (ControlCycle.recoverable): the arrays are the problem's own.
        self._row_cycle = ControlCycle(self.dt, self.problem.lb, self.problem.ub, horizon)

    def conflicting_constraints(self) -> list[str]:
        """The irreducible conflicting set of the last infeasible cycle (deletion filter with
        daqp, computed now, off the control cycle); [] when no cycle was infeasible."""
        if self._last_infeasible is None:
            return []
        return self._irreducible_conflict(*self._last_infeasible)

    # ------------------------------------------------------------------ public API
    def reset(self, q, dq=None) -> None:
        """Re-initialise the command memory at the state (q, dq) (zero acceleration) and
        re-capture the task targets left unspecified."""
        terms = self.robot.terms(q, dq, check_limits=False)
        self.memory = CommandMemory(terms.q.copy(), terms.dq.copy(), np.zeros(NQ))
        for task in self.tasks:
            task.reset(terms)
        self._targets_set = True

    def step(self, q, dq) -> Command:
        """One control cycle. Never raises on a bad state or a solver failure: see the module
        docstring for the fallback."""
        robot = self.robot
        try:
            if self._terms is None:
                self._terms = robot.terms(q, dq)
            else:
                robot.update_terms(self._terms, q, dq)
        except InvalidStateError as error:
            return self._fallback(q, dq, STATUS_FALLBACK_INVALID_STATE, [error.constraint], str(error))
        except SingularPostureError as error:
            return self._fallback(q, dq, STATUS_FALLBACK_SINGULAR, [], str(error))
        terms = self._terms
        over = first_outside(terms.dq, robot.dq_max)
        if over >= 0:
            message = f"dq{over + 1} = {terms.dq[over]:.4f} rad/s is outside the velocity limits"
            return self._fallback(q, dq, STATUS_FALLBACK_INVALID_STATE, ["joint_velocity_limit"], message, terms)
        if not self._targets_set:
            for task in self.tasks:
                task.reset(terms)
            self._targets_set = True

        self._cycle.advance(self.memory.ddq, self.ddq_max, self._jerk_step)
        if not self._assemble(terms, self._cycle):
            return self._infeasible(q, dq, terms, "the joint-space bounds conflict")

        status, ddq, solver_name = self._solve()
        if status == INFEASIBLE:
            return self._infeasible(q, dq, terms, f"the QP is infeasible (confirmed by {solver_name})")
        if status != SOLVED:
            return self._fallback(q, dq, STATUS_FALLBACK_SOLVER_ERROR, [], "no solver found a solution", terms)

        dq_cmd, q_cmd = np.empty(NQ), np.empty(NQ)
        status = STATUS_OK
        # dq_cmd = dq + ddq dt (clipped only off the closed loop: see the docstring) and
        # q_cmd = q + (dq + dq_cmd) dt / 2 within the position limits
        if integrate_command(terms.q, terms.dq, ddq, self.dt, robot.dq_max, robot.q_min, robot.q_max, dq_cmd, q_cmd):
            ddq = (dq_cmd - terms.dq) * (1.0 / self.dt)
            status = STATUS_VELOCITY_CLIPPED
            self.problem.violation(ddq)  # the gaps of the ddq actually commanded
        return self._emit(terms, ddq, dq_cmd, q_cmd, status, self._active_constraints(ddq), [], solver_name)

    # ------------------------------------------------------------------ one cycle
    def _assemble(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Fill the preallocated QP data from the tasks and constraints of this state; False
        when the joint-space bounds conflict (lb > ub somewhere)."""
        self._assemble_tasks(terms)
        return self._assemble_constraints(terms, cycle)

    def _assemble_tasks(self, terms: ModelTerms) -> None:
        """Cost: H = A^T W A and g = -A^T W b over the stacked rows of every task."""
        for task, A, b, w in self._task_views:
            task.compute_into(terms, A, b)
            w[:] = task.weight
        weighted_least_squares(self._task_A, self._task_b, self._task_w[:, 0], self.problem.H, self.problem.g)

    def _assemble_constraints(self, terms: ModelTerms, cycle: ControlCycle) -> bool:
        """Bounds: the box constraints intersected and clipped into the cycle's reachable
        accelerations, then the general rows, the relaxed ones relaxed in one block. False when
        the box bounds conflict."""
        problem = self.problem
        box_lower, box_upper = self._box_lower, self._box_upper
        for k, constraint in enumerate(self.box_constraints):
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

    def _solve(self) -> tuple[str, np.ndarray | None, str]:
        """Solve with the chosen solver; a second solver confirms any failure or inaccurate
        answer. Returns (status, ddq, name of the solver whose answer counts)."""
        problem = self.problem
        try:
            status, x = self.solver.solve(problem)
        except Exception:  # a backend error must not stop the control loop
            status, x = FAILED, None
        if status == SOLVED and self._acceptable(x):
            return SOLVED, x, self.solver.name
        try:
            status, x = self.verifier.solve(problem)
        except Exception:
            status, x = FAILED, None
        if status == SOLVED and not self._acceptable(x):
            status, x = FAILED, None
        return status, x, self.verifier.name

    def _acceptable(self, x: np.ndarray) -> bool:
        """A solution is used only when it is finite and satisfies every row and bound."""
        return self.problem.violation(x) <= self.feasibility_tolerance

    def _active_constraints(self, ddq: np.ndarray) -> list[str]:
        """Names of the constraints with at least one row at a bound (the gaps of the
        accepted solution's feasibility check; box constraints by their own, unclipped bounds)."""
        p = self.problem
        flags = self._active_flags
        tight_constraints(ddq, self._box_bounds, p.lower_gap, p.upper_gap, self._row_ends, self.feasibility_tolerance * 10.0, flags)
        return [name for name, hit in zip(self._flag_names, flags) if hit]

    def reference_active_constraints(self, ddq: np.ndarray) -> list[str]:
        """``_active_constraints`` in plain numpy (the reference of its kernel)."""
        tol = self.feasibility_tolerance * 10.0
        box_tight = (np.abs(self._box_bounds - ddq) <= tol).any(axis=1)
        active = [c.name for c, lower, upper in zip(self.box_constraints, box_tight[0::2], box_tight[1::2]) if lower or upper]
        if self._row_slices:
            p = self.problem
            tight = np.minimum(p.lower_gap[NQ:], p.upper_gap[NQ:]) <= tol
            per_constraint = np.logical_or.reduceat(tight, self._row_starts)
            active += [c.name for c, hit in zip(self.row_constraints, per_constraint) if hit]
        return active

    def _infeasible(self, q, dq, terms, message) -> Command:
        self._last_infeasible = (self.problem.copy(), self._box_lower.copy(), self._box_upper.copy())
        conflict = self._bounded_conflict()
        return self._fallback(
            q, dq, STATUS_FALLBACK_INFEASIBLE, conflict, f"{message}; conflict: {', '.join(conflict)}", terms
        )

    def _bounded_conflict(self) -> list[str]:
        """A conflicting set from one interval test (module docstring): over the box
        lb <= ddq <= ub, C_i ddq spans [r_i, R_i]; a row with u_i < r_i or l_i > R_i conflicts
        with the box. Compiled (``interval_conflicts``)."""
        p = self.problem
        flags = self._active_flags
        consistent = interval_conflicts(self._box_bounds, p.lb, p.ub, p.C, p.l, p.u, self._row_ends, flags)
        return self._conflict_names(flags, consistent)

    def reference_interval_conflicts(self, flags: np.ndarray) -> bool:
        """``interval_conflicts`` on this cycle's problem in plain numpy (the reference of its
        kernel): the same flags and the same return value."""
        p = self.problem
        n_boxes = len(self.box_constraints)
        flags[:n_boxes] = ((self._box_lower == p.lb) | (self._box_upper == p.ub)).any(axis=1)
        flags[n_boxes:] = False
        if (p.lb > p.ub).any():
            return False
        if self._row_slices:
            low, high = p.C * p.lb, p.C * p.ub
            unreachable = (p.u < np.minimum(low, high).sum(axis=1)) | (p.l > np.maximum(low, high).sum(axis=1))
            flags[n_boxes:] = np.logical_or.reduceat(unreachable, self._row_starts)
        return True

    def _conflict_names(self, flags: np.ndarray, box_consistent: bool) -> list[str]:
        """The names of ``interval_conflicts``' flags: the conflicting rows (every general
        constraint when none is flagged) then the boxes that set a bound; the boxes alone when
        the box itself is empty or there are no general rows."""
        n_boxes = len(self.box_constraints)
        boxes = [name for name, hit in zip(self._flag_names[:n_boxes], flags[:n_boxes]) if hit]
        if not box_consistent or not self._row_slices:
            return boxes
        rows = [name for name, hit in zip(self._flag_names[n_boxes:], flags[n_boxes:]) if hit]
        return (rows or self._flag_names[n_boxes:]) + boxes

    def _irreducible_conflict(self, problem: QpProblem, box_lower: np.ndarray, box_upper: np.ndarray) -> list[str]:
        """An irreducible infeasible subset of the constraints of a stored infeasible cycle
        (deletion filter: one daqp feasibility solve per constraint)."""
        rows = {c.name: (None, lower, upper) for c, lower, upper in zip(self.box_constraints, box_lower, box_upper)}
        for c, s in zip(self.row_constraints, self._row_slices):
            rows[c.name] = (problem.C[s], problem.l[s], problem.u[s])

        def feasible(names: list[str]) -> bool:
            lb, ub = np.full(NQ, -np.inf), np.full(NQ, np.inf)
            C, l, u = [np.zeros((0, NQ))], [np.zeros(0)], [np.zeros(0)]
            for name in names:
                C_rows, lower, upper = rows[name]
                if C_rows is None:
                    lb, ub = np.maximum(lb, lower), np.minimum(ub, upper)
                else:
                    C.append(C_rows)
                    l.append(lower)
                    u.append(upper)
            if np.any(lb > ub):
                return False
            C = np.vstack(C)
            check = QpProblem(np.eye(NQ), np.zeros(NQ), C, np.concatenate(l), np.concatenate(u), lb, ub)
            return DaqpSolver(C.shape[0]).solve(check)[0] == SOLVED

        kept = [c.name for c in self.constraints]
        for name in list(kept):
            trial = [n for n in kept if n != name]
            if not feasible(trial):
                kept = trial
        return kept

    def _fallback(self, q, dq, status, violated, message, terms: ModelTerms | None = None) -> Command:
        """Joint-wise braking within the acceleration and jerk limits (module docstring)."""
        self.fallback_count += 1
        robot = self.robot
        q, dq = self._usable_state(q, dq)
        ddq, dq_cmd, q_cmd = np.empty(NQ), np.empty(NQ), np.empty(NQ)
        braking_command(
            q, dq, self.memory.ddq, self.ddq_max, self._jerk_step, self.dt, robot.dq_max, robot.q_min, robot.q_max,
            ddq, dq_cmd, q_cmd,
        )
        return self._emit(terms, ddq, dq_cmd, q_cmd, status, [], list(violated), "", message)

    def reference_braking_command(self, q, dq) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``braking_command`` in plain numpy (the reference of its kernel): ddq, dq_cmd, q_cmd."""
        robot = self.robot
        cycle = ControlCycle.after(self.memory.ddq, self.dt, self.ddq_max, self.dddq_max)
        ddq = np.clip(-dq / self.dt, cycle.acceleration_lower, cycle.acceleration_upper)
        dq_cmd = np.clip(dq + ddq * self.dt, -robot.dq_max, robot.dq_max)
        q_cmd = np.clip(q + (0.5 * self.dt) * (dq + dq_cmd), robot.q_min, robot.q_max)
        return ddq, dq_cmd, q_cmd

    def _usable_state(self, q, dq) -> tuple[np.ndarray, np.ndarray]:
        """(q, dq) if finite with the right shapes, else the previous command."""
        try:
            q = np.asarray(q, dtype=float).reshape(NQ)
            dq = np.asarray(dq, dtype=float).reshape(NQ)
        except (TypeError, ValueError):
            q = dq = np.full(NQ, np.nan)
        if all_finite(q, dq):
            return q, dq
        if self.memory.q_cmd is not None:
            return self.memory.q_cmd, self.memory.dq_cmd
        mid_range = 0.5 * (self.robot.q_min + self.robot.q_max)
        return np.where(np.isfinite(q), q, mid_range), np.zeros(NQ)

    def _emit(self, terms, ddq, dq_cmd, q_cmd, status, active, violated, solver, message="") -> Command:
        """Record the command in the memory and package it with the impact prediction (the
        maps of this cycle, already computed for the impact constraints)."""
        memory = self.memory
        memory.q_cmd, memory.dq_cmd, memory.ddq = q_cmd, dq_cmd, ddq
        if self.impact is not None and terms is not None:
            maps = self.impact.maps(terms)
            jump = maps.jump_matrix @ dq_cmd
            impact_active = maps.active
        else:
            jump = np.zeros(NQ)
            impact_active = False
        return Command(
            ddq, dq_cmd, q_cmd, status, active, violated, jump, dq_cmd + jump, impact_active, solver, message,
            self.phase,
        )


def _consecutive_slices(sizes: list[int]) -> list[slice]:
    ends = np.cumsum(sizes, dtype=int)
    return [slice(int(end - size), int(end)) for size, end in zip(sizes, ends)]


@njit(cache=True)
def weighted_least_squares(A, b, w, H, g):
    """Kernel: H = A^T diag(w) A and g = -A^T diag(w) b, the QP cost of the stacked task rows."""
    rows, n = A.shape
    for i in range(n):
        g[i] = 0.0
        for j in range(n):
            H[i, j] = 0.0
    for r in range(rows):
        for i in range(n):
            wa = w[r] * A[r, i]
            g[i] -= wa * b[r]
            for j in range(i, n):
                H[i, j] += wa * A[r, j]
    for i in range(n):
        for j in range(i):
            H[i, j] = H[j, i]


@njit(cache=True)
def intersect_boxes(box_lower, box_upper, reachable_lower, reachable_upper, lb, ub):
    """Kernel: lb = max_k box_lower[k] and ub = min_k box_upper[k], each clipped into the
    reachable interval [reachable_lower, reachable_upper]; False when lb > ub somewhere."""
    consistent = True
    for j in range(lb.shape[0]):
        low, high = -np.inf, np.inf
        for k in range(box_lower.shape[0]):
            low = max(low, box_lower[k, j])
            high = min(high, box_upper[k, j])
        lb[j] = min(max(low, reachable_lower[j]), reachable_upper[j])
        ub[j] = min(max(high, reachable_lower[j]), reachable_upper[j])
        if lb[j] > ub[j]:
            consistent = False
    return consistent


@njit(cache=True)
def first_outside(values, limit):
    """Kernel: the first index with |values_i| > limit_i, -1 when there is none."""
    for i in range(values.shape[0]):
        if abs(values[i]) > limit[i]:
            return i
    return -1


@njit(cache=True)
def integrate_command(q, dq, ddq, dt, dq_max, q_min, q_max, dq_cmd, q_cmd):
    """Kernel: dq_cmd = clip(dq + ddq dt, +-dq_max), q_cmd = clip(q + (dq + dq_cmd) dt / 2,
    q_min, q_max); True when dq_cmd had to be clipped."""
    clipped = False
    for i in range(q.shape[0]):
        v = dq[i] + ddq[i] * dt
        if v > dq_max[i]:
            v, clipped = dq_max[i], True
        elif v < -dq_max[i]:
            v, clipped = -dq_max[i], True
        dq_cmd[i] = v
        q_cmd[i] = min(max(q[i] + 0.5 * dt * (dq[i] + v), q_min[i]), q_max[i])
    return clipped


@njit(cache=True)
def stacked_violation(C, x, lower, upper, lower_gap, upper_gap):
    """Kernel of ``QpProblem.violation``: with z = [x; C x], lower_gap = z - lower and
    upper_gap = upper - z; the largest violation max(0, -min gaps), inf for a non-finite x."""
    n = x.shape[0]
    worst = 0.0
    for i in range(n + C.shape[0]):
        if i < n:
            z = x[i]
        else:
            z = 0.0
            for j in range(n):
                z += C[i - n, j] * x[j]
        if not np.isfinite(z):
            return np.inf
        lower_gap[i] = z - lower[i]
        upper_gap[i] = upper[i] - z
        worst = max(worst, -lower_gap[i], -upper_gap[i])
    return worst


@njit(cache=True)
def tight_constraints(x, box_bounds, lower_gap, upper_gap, row_ends, tol, flags):
    """Kernel: flags[k] for box k (bounds in rows 2k, 2k+1 of box_bounds) when x is within tol
    of one of its bounds, then flags of the general constraints (rows ending at row_ends) when
    one of their rows has a gap <= tol."""
    boxes = box_bounds.shape[0] // 2
    n = x.shape[0]
    for k in range(boxes):
        hit = False
        for j in range(n):
            if abs(box_bounds[2 * k, j] - x[j]) <= tol or abs(box_bounds[2 * k + 1, j] - x[j]) <= tol:
                hit = True
                break
        flags[k] = hit
    start = 0
    for c in range(row_ends.shape[0]):
        hit = False
        for r in range(start, row_ends[c]):
            if min(lower_gap[n + r], upper_gap[n + r]) <= tol:
                hit = True
                break
        flags[boxes + c] = hit
        start = row_ends[c]


@njit(cache=True)
def interval_conflicts(box_bounds, lb, ub, C, l, u, row_ends, flags):
    """Kernel of the interval test of an infeasible cycle: flags[k] for box k when one of its
    bounds (rows 2k, 2k+1 of box_bounds) sets the intersected box [lb, ub]; then, when that box
    is not empty, flags of the general constraints (rows ending at row_ends) when one of their
    rows has u_i < r_i or l_i > R_i, [r_i, R_i] the span of C_i x over the box. Returns whether
    the box is consistent (lb <= ub)."""
    boxes = box_bounds.shape[0] // 2
    n = lb.shape[0]
    for k in range(boxes):
        hit = False
        for j in range(n):
            if box_bounds[2 * k, j] == lb[j] or box_bounds[2 * k + 1, j] == ub[j]:
                hit = True
                break
        flags[k] = hit
    for c in range(row_ends.shape[0]):
        flags[boxes + c] = False
    for j in range(n):
        if lb[j] > ub[j]:
            return False
    start = 0
    for c in range(row_ends.shape[0]):
        hit = False
        for i in range(start, row_ends[c]):
            low = 0.0
            high = 0.0
            for j in range(n):
                a = C[i, j] * lb[j]
                b = C[i, j] * ub[j]
                low += min(a, b)
                high += max(a, b)
            if u[i] < low or l[i] > high:
                hit = True
                break
        flags[boxes + c] = hit
        start = row_ends[c]
    return True


@njit(cache=True)
def braking_command(q, dq, previous_ddq, ddq_max, jerk_step, dt, dq_max, q_min, q_max, ddq, dq_cmd, q_cmd):
    """Kernel of the fallback: ddq = -dq / dt clipped into the reachable interval
    [max(-ddq_max, ddq_prev - s), min(ddq_max, ddq_prev + s)] (s = dddq_max dt), dq_cmd = dq + ddq dt
    within +-dq_max and q_cmd = q + (dq + dq_cmd) dt / 2 within [q_min, q_max]."""
    for j in range(q.shape[0]):
        lower = max(-ddq_max[j], previous_ddq[j] - jerk_step[j])
        upper = min(ddq_max[j], previous_ddq[j] + jerk_step[j])
        ddq[j] = min(max(-dq[j] / dt, lower), upper)
        dq_cmd[j] = min(max(dq[j] + ddq[j] * dt, -dq_max[j]), dq_max[j])
        q_cmd[j] = min(max(q[j] + 0.5 * dt * (dq[j] + dq_cmd[j]), q_min[j]), q_max[j])
