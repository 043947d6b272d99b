"""The linear-algebra kernels of the jump maps (controller/model/jump_kernels.py) against numpy:
the held contacts' symmetric positive-definite solve."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.jump_kernels import cholesky_solve_in_place


@settings(max_examples=200, deadline=None)
@given(size=st.integers(1, 18), columns=st.integers(1, 4), seed=st.integers(0, 2**32 - 1))
def test_a_positive_definite_system_is_solved_as_numpy_solves_it(size, columns, seed):
    """S = Y Y^T + eps I (a Gram matrix such as Jf M^-1 Jf^T, conditioned up to about 1e6): x with
    S x = b to the conditioning's rounding; a rank-deficient Gram matrix is refused."""
    rng = np.random.default_rng(seed)
    Y = rng.normal(size=(size, size + 3)) * rng.uniform(1e-3, 1.0, size)[:, None]
    S = Y @ Y.T
    B = rng.normal(size=(size, columns))
    factor, x = S.copy(), B.copy()
    assert cholesky_solve_in_place(factor, x)
    expected = np.linalg.solve(S, B)
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-9 * np.linalg.cond(S) * np.abs(expected).max())
    np.testing.assert_allclose(S @ x, B, rtol=0, atol=1e-8 * np.abs(S).max() * np.abs(x).max())
    if size > 1:
        deficient = Y[:, :1] @ Y[:, :1].T  # rank one
        assert not cholesky_solve_in_place(deficient.copy(), B.copy())
