"""The classical prediction's compiled fixed-base matrices (``controller.model.classical_matrices``):
its numpy statement, and the identities of eqs. (5)-(6) they must satisfy."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.jump import reference_classical_jump_matrices

from conftest import JOINTS, random_state
from impactqp.controller.model.classical_matrices import classical_jump_matrices

SEEDS = st.integers(0, 2**32 - 1)


def compiled(terms, restitution):
    out = (np.empty((JOINTS, JOINTS)), np.empty((JOINTS, JOINTS)), np.empty((3, 3)))
    classical_jump_matrices(terms.M_inv, terms.J, restitution, *out)
    return out


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, restitution=st.floats(0.0, 1.0))
def test_compiled_matrices_equal_the_numpy_reference(robot, seed, restitution):
    terms = random_state(robot, np.random.default_rng(seed))
    for fast, reference in zip(compiled(terms, restitution), reference_classical_jump_matrices(terms, restitution)):
        np.testing.assert_allclose(fast, reference, rtol=0.0, atol=1e-12 * np.abs(reference).max())


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, restitution=st.floats(0.0, 1.0))
def test_the_contact_velocity_after_the_jump_is_minus_the_restitution_times_before(robot, seed, restitution):
    """Eq. (5): the full 3-D impulse takes v- = J dq- to -c_r v-, J (I + A) = -c_r J; the jump is
    the momentum law M A = J^T G J = P, and P is symmetric."""
    terms = random_state(robot, np.random.default_rng(seed))
    A, P, G = compiled(terms, restitution)
    J = terms.J
    scale = np.abs(J).max()
    np.testing.assert_allclose(J @ A, -(1.0 + restitution) * J, rtol=0.0, atol=1e-9 * scale)
    np.testing.assert_allclose(terms.M @ A, P, rtol=0.0, atol=1e-9 * np.abs(P).max())
    np.testing.assert_allclose(P, P.T, rtol=0.0, atol=1e-12 * np.abs(P).max())
    np.testing.assert_allclose(J.T @ G @ J, P, rtol=0.0, atol=1e-12 * np.abs(P).max())
