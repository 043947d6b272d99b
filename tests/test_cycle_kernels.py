"""The compiled kernels of one control cycle (controller/qp/cycle_kernels.py) against their plain
numpy twins: the QP cost of the stacked task rows."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.qp.cycle_kernels import weighted_least_squares


@settings(max_examples=200, deadline=None)
@given(
    rows=st.integers(0, 40), n=st.integers(1, 36), density=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1)
)
def test_the_cost_of_the_task_rows_is_their_weighted_normal_equations(rows, n, density, seed):
    """H = A^T diag(w) A and g = -A^T diag(w) b for stacked rows of any sparsity (a dense
    centre-of-mass row, a frame's chain) and single-entry rows whose column is given (a posture
    or damping row), any non-negative weights, zero ones included; H exactly symmetric; stale
    values in H and g overwritten."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(rows, n)) * (rng.random((rows, n)) < density)
    columns = np.where(rng.random(rows) < 0.5, rng.integers(0, n, rows), -1)
    for r in np.flatnonzero(columns >= 0):
        A[r] = 0.0
        A[r, columns[r]] = rng.normal()
    b, w = rng.normal(size=rows), rng.uniform(0.0, 10.0, rows) * (rng.random(rows) < 0.8)
    H, g = np.full((n, n), np.nan), np.full(n, np.nan)
    weighted_least_squares(A, b, w, columns, H, g)
    np.testing.assert_allclose(H, A.T @ (w[:, None] * A), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(g, -A.T @ (w * b), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(H, H.T)
