"""QP solver backends: each ``solve(problem) -> (status, x)`` on a ``QpProblem``.

``daqp`` (the default) works on the preallocated, stacked bounds in one workspace of its own,
updated in place and warm-started every cycle. ``proxqp`` is
proxsuite dense, initialised once and then updated and warm-started every cycle. Any other
name goes through ``qpsolvers.solve_problem(..., solver=name)`` (one-shot, no warm start);
``"qpsolvers:proxqp"`` forces proxqp through qpsolvers. ``QuadprogSolver`` (Goldfarb-Idnani)
is the independent second opinion the controller asks when daqp fails (docs/qp-constraints.md,
Solvers).
"""

from __future__ import annotations

import numpy as np
import proxsuite
import qpsolvers
import quadprog

from impactqp.controller.model.validation import BadInputError

from .daqp_api import DaqpWorkspace
from .problem import QpProblem

SOLVED, INFEASIBLE, FAILED = "solved", "infeasible", "failed"
_PROXQP_INFINITY = 1e20
PROXQP_OUTER_ITERATIONS = 20  # a feasible cycle of the arm or the G1 needs 3-9
PROXQP_INNER_ITERATIONS = 10  # per outer iteration; a feasible cycle needs 1-3 on average
_WARM_START = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
_COLD_START = proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS


class ProxqpDenseSolver:
    """proxsuite dense QP, initialised once and then updated and warm-started every cycle (from
    the previous solution and multipliers, with proxqp's default proximal parameters mu: left to
    proxqp, the mu of one cycle (down to 1e-8) start the next, and from them proxqp called
    feasible G1 QPs primal infeasible after one iteration); a failure makes the next cycle start
    cold from a fresh init."""

    name = "proxqp"

    def __init__(self, rows: int, variables: int, tolerance: float = 1e-7):
        self.qp = proxsuite.proxqp.dense.QP(variables, 0, rows, True)
        settings = self.qp.settings
        # Bounded cycle time: at most OUTER x (INNER + 1) inner iterations (a second solver
        # confirms any failure). proxqp's max_iter counts outer (proximal) iterations, each of up
        # to max_iter_in + 1 inner ones: 200 and 200 allowed 40,200, about 1 s on an infeasible G1
        # QP that proxqp's own infeasibility test did not catch.
        settings.max_iter = PROXQP_OUTER_ITERATIONS
        settings.max_iter_in = PROXQP_INNER_ITERATIONS
        settings.eps_abs = tolerance
        settings.eps_rel = 0.0
        # Primal and dual residuals alone accept a warm start whose multipliers sit on bounds
        # that are no longer active (only the bounds moved): the duality gap catches that.
        settings.check_duality_gap = True
        settings.eps_duality_gap_abs = tolerance
        settings.eps_duality_gap_rel = 0.0
        settings.verbose = False
        self._mu_eq, self._mu_in = settings.default_mu_eq, settings.default_mu_in
        self.initialized = False
        self._l = np.zeros(rows)
        self._u = np.zeros(rows)

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        l = np.maximum(problem.l, -_PROXQP_INFINITY, out=self._l)
        u = np.minimum(problem.u, _PROXQP_INFINITY, out=self._u)
        data = (problem.H, problem.g, None, None, problem.C, l, u, problem.lb, problem.ub)
        if self.initialized:
            self.qp.update(*data, mu_eq=self._mu_eq, mu_in=self._mu_in)
            self.qp.settings.initial_guess = _WARM_START
        else:  # the first cycle, or the one after a failure: a cold start
            self.qp.init(*data, mu_eq=self._mu_eq, mu_in=self._mu_in)
            self.qp.settings.initial_guess = _COLD_START
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
    """daqp on the stacked bounds [lb; l] <= [x; C x] <= [ub; u] through one workspace of its own
    (``daqp_api.DaqpWorkspace``: daqp's C functions, the problem's arrays read in place): set up
    at the first solve of a problem, its data updated at every later solve of the same problem,
    which starts from the previous working set (warm start). A failed setup, update or solve
    makes the next solve start afresh (a cold setup). daqp's exit flag -1 says infeasible: a
    failed setup or update is an inconsistent box (lb > ub)."""

    name = "daqp"

    def __init__(self, rows: int, variables: int):
        self._workspace = DaqpWorkspace(rows, variables)
        self._problem: QpProblem | None = None  # the problem the workspace is set up for

    def workspace_for(self, problem: QpProblem) -> DaqpWorkspace | None:
        """The workspace when it is set up for ``problem`` (a compiled caller may then solve in it:
        ``solved_command.SolvedCommand``), else None."""
        return self._workspace if problem is self._problem else None

    def forget(self) -> None:
        """Start the next solve afresh (a compiled caller's solve failed)."""
        self._problem = None

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        if problem is self._problem:
            exitflag, x = self._workspace.solve()
        else:
            exitflag = self._workspace.setup(problem)
            self._problem = problem
            if exitflag >= 0:
                exitflag, x = self._workspace.solve()
        if exitflag >= 1:
            return SOLVED, x
        self._problem = None
        return (INFEASIBLE if exitflag == -1 else FAILED), None


class QuadprogSolver:
    """quadprog (Goldfarb-Idnani dual active set), the independent second opinion for daqp.

    It solves min 1/2 x^T H x - a^T x s.t. A^T x >= b with the first meq rows equalities, so a
    row or bound with lower = upper becomes one equality (as two opposite inequalities it is
    degenerate, and quadprog calls such problems inconsistent) and every other finite bound one
    inequality. quadprog reports an infeasible problem only by a ValueError whose text says the
    constraints are inconsistent; any other error is a failure.
    """

    name = "quadprog"

    def __init__(self, rows: int, variables: int):
        del rows, variables  # quadprog takes the problem as it comes

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        equal = np.isfinite(problem.upper) & (problem.upper == problem.lower)
        upper = np.isfinite(problem.upper) & ~equal
        lower = np.isfinite(problem.lower) & ~equal
        identity_and_rows = np.vstack([np.eye(problem.H.shape[0]), problem.C])
        A = np.vstack([identity_and_rows[equal], -identity_and_rows[upper], identity_and_rows[lower]])
        b = np.concatenate([problem.lower[equal], -problem.upper[upper], problem.lower[lower]])
        try:
            x = quadprog.solve_qp(problem.H, -problem.g, A.T, b, int(equal.sum()))[0]
        except ValueError as error:
            return (INFEASIBLE if "inconsistent" in str(error) else FAILED), None
        return SOLVED, x


class QpsolversSolver:
    """Any backend of ``qpsolvers`` (one-shot: no warm start); l <= C x <= u becomes
    [C; -C] x <= [u; -l] without the unbounded rows, and a row with l = u the equality C_i x = u_i."""

    def __init__(self, backend: str):
        if backend not in qpsolvers.available_solvers:
            raise BadInputError(
                f"QP solver {backend!r} is not available; available: "
                f"daqp (direct), proxqp (direct, warm-started), "
                f"{', '.join(qpsolvers.available_solvers)} (through qpsolvers)"
            )
        self.backend = backend
        self.name = f"qpsolvers:{backend}"

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        equal = np.isfinite(problem.u) & (problem.u == problem.l)
        G = np.vstack([problem.C[~equal], -problem.C[~equal]])
        h = np.concatenate([problem.u[~equal], -problem.l[~equal]])
        finite = np.isfinite(h)
        A, b = (problem.C[equal], problem.u[equal]) if np.any(equal) else (None, None)
        solution = qpsolvers.solve_problem(
            qpsolvers.Problem(problem.H, problem.g, G[finite], h[finite], A, b, lb=problem.lb, ub=problem.ub),
            solver=self.backend,
        )
        if solution.found and solution.x is not None and np.all(np.isfinite(solution.x)):
            return SOLVED, np.asarray(solution.x, dtype=float)
        return FAILED, None


def available_backends() -> list[str]:
    """Every solver name ``make_solver`` accepts on this machine."""
    return ["daqp", "proxqp"] + [f"qpsolvers:{name}" for name in qpsolvers.available_solvers]


def make_solver(name: str, rows: int, variables: int):
    """The QP backend called ``name`` (see the module docstring) for ``rows`` general rows in
    ``variables`` unknowns."""
    if name == "proxqp":
        return ProxqpDenseSolver(rows, variables)
    if name == "daqp":
        return DaqpSolver(rows, variables)
    return QpsolversSolver(name.removeprefix("qpsolvers:"))


def verifier_for(name: str, rows: int, variables: int) -> DaqpSolver | QuadprogSolver:
    """The independent solver that confirms the failures of the backend ``name``: quadprog
    behind daqp, daqp behind every other backend."""
    return QuadprogSolver(rows, variables) if name == "daqp" else DaqpSolver(rows, variables)
