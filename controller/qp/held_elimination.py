"""daqp on a standing robot's QP with its held contacts' equality rows eliminated (docs/whole-body-qp.md,
"Controller cycle").

The QP min 1/2 x^T H x + g^T x over lb <= x <= ub, l <= C x <= u holds the held contacts' rows
Jf x = d (``HeldContactRows``: d = -dJf v). Split the unknowns into e, the velocities of the
joints that carry the held frames (a standing robot's legs: one 6-joint chain per foot, so Jf_e
is square) and f, the others (the base's and the upper body's). Where Jf_e is invertible, the
rows give x_e = E x_f + e0 with E = -Jf_e^-1 Jf_f and e0 = Jf_e^-1 d, and the QP is the same as

    min 1/2 x_f^T H_r x_f + g_r^T x_f   over lb_f <= x_f <= ub_f, l - C_e e0 <= C_r x_f <= u - C_e e0,
                                              lb_e - e0 <= E x_f <= ub_e - e0,
    H_r = H_ff + H_fe E + E^T H_ef + E^T H_ee E,   g_r = g_f + E^T g_e + (H_fe + E^T H_ee) e0,
    C_r = C_f + C_e E,

with x_e = E x_f + e0 after: the same minimiser (an exact substitution), m - 12 unknowns instead
of m, no equality row (the rows of e's bounds take the held rows' places, so the row count and
order stay). daqp adds each equality row to its working set one iteration at a time; without
them it solves the G1's QP in about half the time. The controller accepts the expanded x only
when it satisfies the full QP (``ImpactAwareController._acceptable``); a singular Jf_e, or a
reduced QP daqp does not solve, goes to daqp on the full QP.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.constraints import HeldContactRows
from impactqp.controller.model.jump_kernels import solve_in_place

from .problem import QpProblem
from .solvers import SOLVED, DaqpSolver


def held_elimination(solver, layout, robot):
    """``solver`` itself, or the daqp solver of the reduced QP (module docstring) when it is daqp
    and the robot stands on held contacts whose rows each move one chain of as many joints."""
    held = [rows for c, rows in zip(layout.row_constraints, layout.row_slices) if type(c) is HeldContactRows]
    if solver.name != "daqp" or len(held) != 1:
        return solver
    eliminated = held_chain_velocities(robot)
    if eliminated is None or len(eliminated) != held[0].stop - held[0].start:
        return solver
    return HeldEliminationDaqp(solver, held[0], eliminated, layout.rows, robot.nv)


def held_chain_velocities(robot) -> np.ndarray | None:
    """The velocity indices of the joints between the floating base and each held frame, in the
    held frames' order, or None when a chain shares a joint with another or is not six joints."""
    model = robot.model
    indices: list[int] = []
    for frame_id in robot.held_frame_ids:
        chain = [j for j in model.supports[model.frames[frame_id].parentJoint] if model.parents[j] > 0]
        columns = [model.joints[j].idx_v + k for j in chain for k in range(model.joints[j].nv)]
        if len(columns) != 6 or set(columns) & set(indices):
            return None
        indices += columns
    return np.array(indices, dtype=np.int64)


class HeldEliminationDaqp:
    """daqp (``DaqpSolver``, warm-started) on the reduced QP, the full QP's daqp the fallback."""

    name = "daqp"

    def __init__(self, full: DaqpSolver, held: slice, eliminated: np.ndarray, rows: int, variables: int):
        self.full = full
        self.held = np.array([held.start, held.stop], dtype=np.int64)
        self.eliminated = eliminated
        self.free = np.setdiff1d(np.arange(variables), eliminated)
        self.reduced = QpProblem.empty(rows, len(self.free))
        self.reduced_solver = DaqpSolver(rows, len(self.free))
        self.substitution = np.zeros((len(eliminated), len(self.free) + 1))  # [E | e0]

    def solve(self, problem: QpProblem) -> tuple[str, np.ndarray | None]:
        r = self.reduced
        if not reduce_problem(
            (problem.H, problem.g, problem.C, problem.lower, problem.upper), (self.held, self.eliminated, self.free),
            self.substitution, (r.H, r.g, r.C, r.lower, r.upper),
        ):  # Jf_e singular at this state
            return self.full.solve(problem)
        status, reduced_x = self.reduced_solver.solve(r)
        if status != SOLVED:
            return self.full.solve(problem)
        x = np.empty(problem.H.shape[0])
        expand_solution(reduced_x, self.substitution, self.eliminated, self.free, x)
        return SOLVED, x


@njit(cache=True)
def reduce_problem(full, partition, substitution, reduced):
    """Kernel: the reduced QP of the module docstring, for full = (H, g, C, [lb; l], [ub; u]),
    partition = ((first, end) of the held rows in C, e, f), into substitution = [E | e0] and
    reduced = (H_r, g_r, C_r, [lb_f; l_r], [ub_f; u_r]); False when a held contact's block of
    Jf_e is singular. Jf_e is block diagonal (each held contact's 6 rows move its own chain,
    ``held_chain_velocities``): one 6 x 6 solve per block. The products run over the columns of
    [E | e0] that have a non-zero entry (a foot's chain moves with the base alone), along the
    rows of H (symmetric: H[:, e] = H[e, :]^T) and of C."""
    H, g, C, lower, upper = full
    held, e, f = partition
    Hr, gr, Cr, lower_r, upper_r = reduced
    n, m, k = H.shape[0], f.shape[0], e.shape[0]
    first, end = held[0], held[1]
    if not held_substitution(C, lower[n + first:n + end], partition, substitution):
        return False
    used = np.empty(m + 1, dtype=np.int64)  # the columns of [E | e0] with a non-zero entry
    count = 0
    for j in range(m + 1):
        for a in range(k):
            if substitution[a, j] != 0.0:
                used[count] = j
                count += 1
                break
    S = np.empty((k, count))  # [E | e0] on its used columns
    for a in range(k):
        for t in range(count):
            S[a, t] = substitution[a, used[t]]
    HE = np.zeros((count, n))  # (H[:, e] [E | e0])^T on the used columns, row by row (H symmetric)
    for t in range(count):
        for a in range(k):
            s = S[a, t]
            if s != 0.0:
                for i in range(n):
                    HE[t, i] += s * H[e[a], i]
    last = count - 1 if count and used[count - 1] == m else count  # the used columns of E (without e0)
    HEe = np.empty((k, count))  # H_ee [E | e0] on the used columns
    for a in range(k):
        for t in range(count):
            HEe[a, t] = HE[t, e[a]]
    for i in range(m):
        lower_r[i], upper_r[i] = lower[f[i]], upper[f[i]]
        gr[i] = g[f[i]]
        for j in range(m):
            Hr[i, j] = H[f[i], f[j]]
    for t in range(count):  # + H_fe E + E^T H_ef, and H_fe e0 in g_r
        j = used[t]
        for i in range(m):
            value = HE[t, f[i]]
            if j == m:
                gr[i] += value
            else:
                Hr[i, j] += value
                Hr[j, i] += value
    for t in range(last):  # + E^T H_ee E and E^T (g_e + H_ee e0): the rows i of E's used columns
        i = used[t]
        for a in range(k):
            s = S[a, t]
            if s == 0.0:
                continue
            gr[i] += s * g[e[a]]
            if last < count:
                gr[i] += s * HEe[a, last]
            for u in range(last):
                Hr[i, used[u]] += s * HEe[a, u]
    reduced_rows(full, partition, (substitution, S, used[:count], last), reduced)
    return True


@njit(cache=True)
def held_substitution(C, held_lower, partition, substitution):
    """Kernel of ``reduce_problem``: [E | e0] (k x (m + 1)) with Jf_e [E | e0] = [-Jf_f | e0's
    right side] (the held rows' C[:, f] and their equality bound ``held_lower``), one 6 x 6
    solve per held contact's block of Jf_e; False when a block is singular."""
    held, e, f = partition
    first, m, k = held[0], f.shape[0], e.shape[0]
    for i in range(k):
        for j in range(m):
            substitution[i, j] = -C[first + i, f[j]]
        substitution[i, m] = held_lower[i]
    block = np.empty((6, 6))
    for b in range(0, k, 6):
        for i in range(6):
            for j in range(6):
                block[i, j] = C[first + b + i, e[b + j]]
        if not solve_in_place(block, substitution[b:b + 6]):
            return False
    return True


@njit(cache=True)
def reduced_rows(full, partition, columns, reduced):
    """Kernel of ``reduce_problem``: the reduced QP's constraint rows C_r and their bounds, for
    columns = ([E | e0], its used columns S, their indices, the number of them that are E's): a
    held row's place takes the bounds of one eliminated velocity, every other row r gets
    C[r, f] + C[r, e] E and its bounds shifted by C[r, e] e0."""
    C, lower, upper = full[2], full[3], full[4]
    held, e, f = partition
    substitution, S, used, last = columns
    Cr, lower_r, upper_r = reduced[2], reduced[3], reduced[4]
    n, m, k, count = full[0].shape[0], f.shape[0], e.shape[0], used.shape[0]
    first, end = held[0], held[1]
    products = np.empty(count)  # C[r, e] [E | e0] on the used columns
    for r in range(C.shape[0]):
        if first <= r < end:  # the held row's place: the bounds of one eliminated velocity
            a = r - first
            Cr[r, :] = substitution[a, :m]
            lower_r[m + r] = lower[e[a]] - substitution[a, m]
            upper_r[m + r] = upper[e[a]] - substitution[a, m]
            continue
        for j in range(m):
            Cr[r, j] = C[r, f[j]]
        products[:] = 0.0
        for a in range(k):
            c = C[r, e[a]]
            if c != 0.0:
                for t in range(count):
                    products[t] += c * S[a, t]
        for t in range(last):
            Cr[r, used[t]] += products[t]
        shift = products[last] if last < count else 0.0
        lower_r[m + r] = lower[n + r] - shift
        upper_r[m + r] = upper[n + r] - shift


@njit(cache=True)
def expand_solution(reduced_x, substitution, e, f, x):
    """Kernel: x_f = the reduced solution, x_e = E x_f + e0."""
    m = f.shape[0]
    for j in range(m):
        x[f[j]] = reduced_x[j]
    for a in range(e.shape[0]):
        total = substitution[a, m]
        for j in range(m):
            total += substitution[a, j] * reduced_x[j]
        x[e[a]] = total
