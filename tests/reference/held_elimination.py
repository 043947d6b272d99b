"""Plain-numpy statement of the reduced QP of ``controller.qp.held_elimination``: the held rows
Jf x = d solved for x_e = E x_f + e0 and substituted, T = dx/dx_f formed in full."""

import numpy as np


def reference_reduced_problem(problem, held: slice, e: np.ndarray, f: np.ndarray) -> tuple:
    """(H_r, g_r, C_r, [lb_f; l_r], [ub_f; u_r], E, e0): x = T x_f + x0 with T = [I; E] (rows f; e)
    and x0 = [0; e0], H_r = T^T H T, g_r = T^T (g + H x0), the rows other than the held ones
    C T with bounds l - C x0, u - C x0, the held rows' places the bounds of x_e: lb_e - e0 <= E x_f
    <= ub_e - e0."""
    n, m = problem.H.shape[0], len(f)
    Jf, d = problem.C[held], problem.l[held]
    solved = np.linalg.solve(Jf[:, e], np.column_stack([-Jf[:, f], d]))
    E, e0 = solved[:, :m], solved[:, m]
    T = np.zeros((n, m))
    T[f, np.arange(m)] = 1.0
    T[e] = E
    x0 = np.zeros(n)
    x0[e] = e0
    Cr = problem.C @ T
    lower, upper = problem.l - problem.C @ x0, problem.u - problem.C @ x0
    Cr[held], lower[held], upper[held] = E, problem.lb[e] - e0, problem.ub[e] - e0
    return (T.T @ problem.H @ T, T.T @ (problem.g + problem.H @ x0), Cr, np.concatenate([problem.lb[f], lower]),
            np.concatenate([problem.ub[f], upper]), E, e0)
