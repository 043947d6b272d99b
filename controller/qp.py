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
``solver="proxqp"`` (default): proxsuite dense, initialised once and then updated and
warm-started every cycle. ``solver="daqp"``: daqp called directly. Any other name is solved
through ``qpsolvers.solve_qp(..., solver=name)``; ``"qpsolvers:proxqp"`` forces proxqp through
qpsolvers. A solution is accepted only when it satisfies every row to ``feasibility_tolerance``
(acceleration units). Warm-started proxsuite 0.8 sometimes reports a feasible QP as infeasible
(docs/qp-constraints.md), so any failed or inaccurate solve is repeated with daqp before the QP
is declared infeasible: the controller never brakes on one solver's false alarm.

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
found with one vectorised interval test (the general constraints whose rows cannot be met
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

from dataclasses import dataclass, field, replace

import daqp
import numpy as np
import proxsuite

from impactqp.constraints import AccelerationLimit, Constraint, ControlCycle, ImpactModel
from impactqp.tasks import Task

from .model.robot import NQ, InvalidStateError, ModelTerms, PandaModel, SingularPostureError
from .model.validation import BadInputError

STATUS_OK = "ok"
STATUS_VELOCITY_CLIPPED = "ok_velocity_clipped"
STATUS_FALLBACK_INFEASIBLE = "fallback_infeasible"
STATUS_FALLBACK_INVALID_STATE = "fallback_invalid_state"
STATUS_FALLBACK_SINGULAR = "fallback_singular_posture"
STATUS_FALLBACK_SOLVER_ERROR = "fallback_solver_error"

_PROXQP_INFINITY = 1e20
_DAQP_INFINITY = 1e30


@dataclass(frozen=True)
class Command:
    """The output of one control cycle for a kinematic-controlled robot.

    ``predicted_jump`` is the joint-velocity jump an impact would cause at the commanded
    velocity (dq- = dq_cmd) with the controller's prediction model, and
    ``predicted_post_impact_velocity`` = dq_cmd + predicted_jump; both are zero when the
    controller has no impact model or the state was unusable. ``phase`` is the phase of the
    impact session that issued the command (``docs/robot-loop.md``).
    """

    ddq: np.ndarray
    dq_cmd: np.ndarray
    q_cmd: np.ndarray
    status: str
    active_constraints: list[str]
    violated_constraints: list[str]
    predicted_jump: np.ndarray
    predicted_post_impact_velocity: np.ndarray
    impact_constraints_active: bool = False
    solver: str = ""
    message: str = ""
    phase: str = "approach"

    @property
    def is_fallback(self) -> bool:
        return self.status not in (STATUS_OK, STATUS_VELOCITY_CLIPPED)


@dataclass
class QpProblem:
    """Preallocated QP data: cost 1/2 x^T H x + g^T x, box lb <= x <= ub, rows l <= C x <= u."""

    H: np.ndarray
    g: np.ndarray
    C: np.ndarray
    l: np.ndarray
    u: np.ndarray
    lb: np.ndarray
    ub: np.ndarray

    @classmethod
    def empty(cls, rows: int) -> QpProblem:
        return cls(
            np.zeros((NQ, NQ)), np.zeros(NQ), np.zeros((rows, NQ)), np.zeros(rows), np.zeros(rows),
            np.zeros(NQ), np.zeros(NQ),
        )

    def violation(self, x: np.ndarray) -> float:
        """Largest violation of a bound or row by x (0 when x is feasible)."""
        Cx = self.C @ x
        return max(
            (self.lb - x).max(), (x - self.ub).max(), (self.l - Cx).max(initial=0.0),
            (Cx - self.u).max(initial=0.0), 0.0,
        )


@dataclass(frozen=True)
class QpOutcome:
    """x is None unless ``status == 'solved'``; status is 'solved', 'infeasible' or 'failed'."""

    x: np.ndarray | None
    status: str


class ProxqpDenseSolver:
    """proxsuite dense QP, initialised once and then updated and warm-started every cycle."""

    name = "proxqp"

    def __init__(self, rows: int, tolerance: float = 1e-7, max_iterations: int = 200):
        self.qp = proxsuite.proxqp.dense.QP(NQ, 0, rows, True)
        settings = self.qp.settings
        settings.max_iter = max_iterations  # bounded cycle time; daqp confirms any failure
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

    def solve(self, problem: QpProblem) -> QpOutcome:
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
            return QpOutcome(self.qp.results.x.copy(), "solved")
        self.initialized = False  # start the next cycle from a fresh init
        if status == proxsuite.proxqp.PROXQP_PRIMAL_INFEASIBLE:
            return QpOutcome(None, "infeasible")
        return QpOutcome(None, "failed")


class DaqpSolver:
    """daqp called directly: simple bounds first, then the general rows."""

    name = "daqp"

    def __init__(self, rows: int):
        self._upper = np.zeros(NQ + rows)
        self._lower = np.zeros(NQ + rows)
        self._sense = np.zeros(NQ + rows, dtype=np.int32)

    def solve(self, problem: QpProblem) -> QpOutcome:
        upper, lower = self._upper, self._lower
        upper[:NQ], upper[NQ:] = problem.ub, problem.u
        lower[:NQ], lower[NQ:] = problem.lb, problem.l
        np.clip(upper, -_DAQP_INFINITY, _DAQP_INFINITY, out=upper)
        np.clip(lower, -_DAQP_INFINITY, _DAQP_INFINITY, out=lower)
        x, _, exitflag, _ = daqp.solve(problem.H, problem.g, problem.C, upper, lower, self._sense)
        if exitflag >= 1:
            return QpOutcome(np.asarray(x, dtype=float), "solved")
        if exitflag == -1:
            return QpOutcome(None, "infeasible")
        return QpOutcome(None, "failed")


class QpsolversSolver:
    """Any backend of ``qpsolvers`` (one-shot: no warm start); l <= C x <= u becomes
    [C; -C] x <= [u; -l] without the unbounded rows."""

    def __init__(self, backend: str):
        import qpsolvers

        if backend not in qpsolvers.available_solvers:
            raise BadInputError(
                f"QP solver {backend!r} is not available; available: "
                f"proxqp (direct, warm-started), daqp (direct), "
                f"{', '.join(qpsolvers.available_solvers)} (through qpsolvers)"
            )
        self.backend = backend
        self.name = f"qpsolvers:{backend}"

    def solve(self, problem: QpProblem) -> QpOutcome:
        import qpsolvers

        G = np.vstack([problem.C, -problem.C])
        h = np.concatenate([problem.u, -problem.l])
        finite = np.isfinite(h)
        solution = qpsolvers.solve_problem(
            qpsolvers.Problem(problem.H, problem.g, G[finite], h[finite], lb=problem.lb, ub=problem.ub),
            solver=self.backend,
        )
        if solution.found and solution.x is not None and np.all(np.isfinite(solution.x)):
            return QpOutcome(np.asarray(solution.x, dtype=float), "solved")
        return QpOutcome(None, "failed")


def available_backends() -> list[str]:
    """Every solver name ``make_solver`` accepts on this machine."""
    import qpsolvers

    return ["proxqp", "daqp"] + [f"qpsolvers:{name}" for name in qpsolvers.available_solvers]


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
    solver : "proxqp" (default), "daqp", or any qpsolvers backend name.
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
        solver: str = "proxqp",
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
        self.row_constraints = [c for c in constraints if not c.is_box]
        self.dt = float(dt)
        self.ddq_max = robot.ddq_max if acceleration_limit is None else np.asarray(acceleration_limit, float)
        self.dddq_max = robot.dddq_max if jerk_limit is None else np.asarray(jerk_limit, float)
        self.impact = impact
        self.feasibility_tolerance = float(feasibility_tolerance)

        self._task_slices = _consecutive_slices([t.rows for t in self.tasks])
        n_task_rows = sum(t.rows for t in self.tasks)
        self._task_A = np.zeros((n_task_rows, NQ))
        self._task_b = np.zeros(n_task_rows)
        self._task_w = np.zeros(n_task_rows)
        self._row_slices = _consecutive_slices([c.rows for c in self.row_constraints])
        self._row_starts = np.array([s.start for s in self._row_slices], dtype=int)
        self.problem = QpProblem.empty(sum(c.rows for c in self.row_constraints))
        self._box_lower = np.zeros((len(self.box_constraints), NQ))
        self._box_upper = np.zeros((len(self.box_constraints), NQ))

        self.solver = make_solver(solver, self.problem.C.shape[0])
        self.verifier = self.solver if self.solver.name == "daqp" else DaqpSolver(self.problem.C.shape[0])
        self.fallback_count = 0
        self.memory = CommandMemory()
        self._targets_set = False
        self._last_infeasible: tuple[ModelTerms, ControlCycle] | None = None
        self.phase = "approach"

    def set_impact_constraints(self, active: bool) -> None:
        """Switch the impact-aware constraints on or off (off: their rows are unbounded, e.g.
        after the impact); the prediction in ``Command`` follows the same switch."""
        models = {id(c.impact): c.impact for c in self.constraints if isinstance(getattr(c, "impact", None), ImpactModel)}
        if self.impact is not None:
            models[id(self.impact)] = self.impact
        for model in models.values():
            model.switched_on = bool(active)
            model._terms = None  # drop the cached activation

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
        try:
            terms = self.robot.terms(q, dq)
        except InvalidStateError as error:
            return self._fallback(q, dq, STATUS_FALLBACK_INVALID_STATE, [_state_constraint(error)], str(error))
        except SingularPostureError as error:
            return self._fallback(q, dq, STATUS_FALLBACK_SINGULAR, [], str(error))
        if (np.abs(terms.dq) > self.robot.dq_max).any():
            over = np.flatnonzero(np.abs(terms.dq) > self.robot.dq_max)
            message = f"dq{over[0] + 1} = {terms.dq[over[0]]:.4f} rad/s is outside the velocity limits"
            return self._fallback(q, dq, STATUS_FALLBACK_INVALID_STATE, ["joint_velocity_limit"], message, terms)
        if not self._targets_set:
            for task in self.tasks:
                task.reset(terms)
            self._targets_set = True

        cycle = ControlCycle.after(self.memory.ddq, self.dt, self.ddq_max, self.dddq_max)
        self._assemble(terms, cycle)
        problem = self.problem
        if np.any(problem.lb > problem.ub):
            return self._infeasible(q, dq, terms, cycle, "the joint-space bounds conflict")

        outcome, solver_name = self._solve()
        if outcome.status == "infeasible":
            return self._infeasible(q, dq, terms, cycle, "the QP is infeasible (confirmed by daqp)")
        if outcome.status != "solved":
            return self._fallback(q, dq, STATUS_FALLBACK_SOLVER_ERROR, [], "no solver found a solution", terms)

        ddq = outcome.x
        robot = self.robot
        dq_cmd = terms.dq + ddq * self.dt
        status = STATUS_OK
        if (np.abs(dq_cmd) > robot.dq_max).any():  # only off the closed loop: see the docstring
            np.minimum(np.maximum(dq_cmd, -robot.dq_max, out=dq_cmd), robot.dq_max, out=dq_cmd)
            ddq = (dq_cmd - terms.dq) * (1.0 / self.dt)
            status = STATUS_VELOCITY_CLIPPED
        q_cmd = terms.q + (0.5 * self.dt) * (terms.dq + dq_cmd)
        np.minimum(np.maximum(q_cmd, robot.q_min, out=q_cmd), robot.q_max, out=q_cmd)
        return self._emit(terms, ddq, dq_cmd, q_cmd, status, self._active_constraints(ddq), [], solver_name)

    # ------------------------------------------------------------------ one cycle
    def _assemble(self, terms: ModelTerms, cycle: ControlCycle) -> None:
        """Fill the preallocated QP data from the tasks and constraints of this state."""
        A, b, w = self._task_A, self._task_b, self._task_w
        for task, rows in zip(self.tasks, self._task_slices):
            A[rows], b[rows], w[rows] = task.compute(terms)
        problem = self.problem
        WA = A * w[:, None]
        np.matmul(A.T, WA, out=problem.H)
        np.matmul(b, WA, out=problem.g)
        np.negative(problem.g, out=problem.g)

        box_lower, box_upper = self._box_lower, self._box_upper
        for k, constraint in enumerate(self.box_constraints):
            _, box_lower[k], box_upper[k] = constraint.compute(terms, cycle)
        np.max(box_lower, axis=0, out=problem.lb)
        np.min(box_upper, axis=0, out=problem.ub)
        # General rows see the joint-space box of this cycle (all box constraints intersected)
        # as the reachable accelerations, so that a row the state violates is relaxed to what
        # the box really allows (ControlCycle.recoverable).
        row_cycle = replace(cycle, acceleration_lower=problem.lb, acceleration_upper=problem.ub)
        for constraint, rows in zip(self.row_constraints, self._row_slices):
            problem.C[rows], problem.l[rows], problem.u[rows] = constraint.compute(terms, row_cycle)

    def _solve(self) -> tuple[QpOutcome, str]:
        """Solve with the chosen solver; confirm any failure or inaccurate answer with daqp."""
        problem = self.problem
        try:
            outcome = self.solver.solve(problem)
        except Exception:  # a backend error must not stop the control loop
            outcome = QpOutcome(None, "failed")
        if self._acceptable(outcome):
            return outcome, self.solver.name
        if self.verifier is self.solver:
            return (outcome if outcome.status != "solved" else QpOutcome(None, "failed")), self.solver.name
        second = self.verifier.solve(problem)
        if second.status == "solved" and not self._acceptable(second):
            second = QpOutcome(None, "failed")
        return second, self.verifier.name

    def _acceptable(self, outcome: QpOutcome) -> bool:
        """A solution is used only when it is finite and satisfies every row and bound."""
        return (
            outcome.status == "solved"
            and bool(np.all(np.isfinite(outcome.x)))
            and self.problem.violation(outcome.x) <= self.feasibility_tolerance
        )

    def _active_constraints(self, ddq: np.ndarray) -> list[str]:
        """Names of the constraints with at least one row at a bound."""
        tol = self.feasibility_tolerance * 10.0
        box_tight = ((ddq - self._box_lower) <= tol) | ((self._box_upper - ddq) <= tol)
        active = [c.name for c, hit in zip(self.box_constraints, box_tight.any(axis=1)) if hit]
        if self._row_slices:
            p = self.problem
            Cx = p.C @ ddq
            tight = ((Cx - p.l) <= tol) | ((p.u - Cx) <= tol)
            per_constraint = np.logical_or.reduceat(tight, self._row_starts)
            active += [c.name for c, hit in zip(self.row_constraints, per_constraint) if hit]
        return active

    def _infeasible(self, q, dq, terms, cycle, message) -> Command:
        self._last_infeasible = (terms, cycle)
        conflict = self._bounded_conflict()
        return self._fallback(
            q, dq, STATUS_FALLBACK_INFEASIBLE, conflict, f"{message}; conflict: {', '.join(conflict)}", terms
        )

    def _bounded_conflict(self) -> list[str]:
        """A conflicting set from one interval test (module docstring): over the box
        lb <= ddq <= ub, C_i ddq spans [r_i, R_i]; a row with u_i < r_i or l_i > R_i conflicts
        with the box."""
        p = self.problem
        boxes = [
            c.name for c, lower, upper in zip(self.box_constraints, self._box_lower, self._box_upper)
            if (lower == p.lb).any() or (upper == p.ub).any()
        ]
        if (p.lb > p.ub).any() or not self._row_slices:
            return boxes
        low, high = p.C * p.lb, p.C * p.ub
        reach_min = np.minimum(low, high).sum(axis=1)
        reach_max = np.maximum(low, high).sum(axis=1)
        unreachable = (p.u < reach_min) | (p.l > reach_max)
        per_constraint = np.logical_or.reduceat(unreachable, self._row_starts)
        rows = [c.name for c, hit in zip(self.row_constraints, per_constraint) if hit]
        return (rows or [c.name for c in self.row_constraints]) + boxes

    def _irreducible_conflict(self, terms: ModelTerms, cycle: ControlCycle) -> list[str]:
        """An irreducible infeasible subset of the constraints (deletion filter, daqp)."""
        rows = {c.name: c.compute(terms, cycle) for c in self.constraints}

        def feasible(names: list[str]) -> bool:
            lb, ub = np.full(NQ, -_DAQP_INFINITY), np.full(NQ, _DAQP_INFINITY)
            C, l, u = [np.zeros((0, NQ))], [np.zeros(0)], [np.zeros(0)]
            for name in names:
                r = rows[name]
                if r.C is None:
                    lb, ub = np.maximum(lb, r.lower), np.minimum(ub, r.upper)
                else:
                    C.append(r.C)
                    l.append(r.lower)
                    u.append(r.upper)
            if np.any(lb > ub):
                return False
            C = np.vstack(C)
            check = QpProblem(np.eye(NQ), np.zeros(NQ), C, np.concatenate(l), np.concatenate(u), lb, ub)
            return DaqpSolver(C.shape[0]).solve(check).status == "solved"

        kept = list(rows)
        for name in list(rows):
            trial = [n for n in kept if n != name]
            if not feasible(trial):
                kept = trial
        return kept

    def _fallback(self, q, dq, status, violated, message, terms: ModelTerms | None = None) -> Command:
        """Joint-wise braking within the acceleration and jerk limits (module docstring)."""
        self.fallback_count += 1
        robot = self.robot
        q, dq = self._usable_state(q, dq)
        cycle = ControlCycle.after(self.memory.ddq, self.dt, self.ddq_max, self.dddq_max)
        ddq = np.clip(-dq / self.dt, cycle.acceleration_lower, cycle.acceleration_upper)
        dq_cmd = np.clip(dq + ddq * self.dt, -robot.dq_max, robot.dq_max)
        q_cmd = np.clip(q + (0.5 * self.dt) * (dq + dq_cmd), robot.q_min, robot.q_max)
        return self._emit(terms, ddq, dq_cmd, q_cmd, status, [], list(violated), "", message)

    def _usable_state(self, q, dq) -> tuple[np.ndarray, np.ndarray]:
        """(q, dq) if finite with the right shapes, else the previous command."""
        try:
            q = np.asarray(q, dtype=float).reshape(NQ)
            dq = np.asarray(dq, dtype=float).reshape(NQ)
        except (TypeError, ValueError):
            q = dq = np.full(NQ, np.nan)
        if np.all(np.isfinite(q)) and np.all(np.isfinite(dq)):
            return q, dq
        if self.memory.q_cmd is not None:
            return self.memory.q_cmd, self.memory.dq_cmd
        mid_range = 0.5 * (self.robot.q_min + self.robot.q_max)
        return np.where(np.isfinite(q), q, mid_range), np.zeros(NQ)

    def _emit(self, terms, ddq, dq_cmd, q_cmd, status, active, violated, solver, message="") -> Command:
        """Record the command in the memory and package it with the impact prediction."""
        self.memory = CommandMemory(q_cmd, dq_cmd, ddq)
        impact_active = False
        if self.impact is not None and terms is not None:
            maps = self.impact.maps(terms)
            jump = maps.jump_matrix @ dq_cmd
            impact_active = maps.active
        else:
            jump = np.zeros(NQ)
        return Command(
            ddq, dq_cmd, q_cmd, status, active, violated, jump, dq_cmd + jump, impact_active, solver, message,
            self.phase,
        )


def _consecutive_slices(sizes: list[int]) -> list[slice]:
    ends = np.cumsum(sizes, dtype=int)
    return [slice(int(end - size), int(end)) for size, end in zip(sizes, ends)]


def _state_constraint(error: InvalidStateError) -> str:
    """The limit an invalid state violates, or 'finite_state' for a malformed state."""
    return "joint_position_limit" if "outside the joint limits" in str(error) else "finite_state"
