"""The fixed base's per-cycle impact kernels (``constraints.impact_cycle_kernels``) against their
numpy statements (``tests/reference/constraints.py``), over random states."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.constraints import reference_fixed_base_cycle_update, reference_normal_motion

from conftest import JOINTS, random_state
from impactqp.constraints.impact_cycle_kernels import (
    classical_cycle_update,
    crb_cycle_update,
    fixed_base_matrix_views,
    gm_cycle_update,
    normal_motion,
)
from impactqp.controller.model.jump import jump_model

SEEDS = st.integers(0, 2**32 - 1)


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS)
def test_compiled_activation_inputs_equal_the_numpy_reference(robot, seed):
    """The compiled n.(J dq) and n.p that the activation rule reads equal their numpy statement."""
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    fast = normal_motion(terms.J, normal, terms.contact_point, terms.dq)
    reference = reference_normal_motion(terms, normal)
    np.testing.assert_allclose(fast, reference, rtol=1e-10, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, name=st.sampled_from(["crb", "gm", "classical"]), restitution=st.floats(0.0, 1.0))
def test_compiled_fixed_base_fill_equals_the_numpy_reference(robot, seed, name, restitution):
    """The one-call fill of an arm's crb, gm or classical impact (A, P, G and the activation
    rule's inputs), from the terms' flat ``contact_terms`` and [n, c_r] into one flat buffer
    [A, P, G], equals its numpy statement, to 1e-12 of each matrix's largest entry; the buffer
    holds A, P and G row-major, one after the other."""
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    model = jump_model(name)
    out = np.full(2 * JOINTS * JOINTS + 9, np.nan)
    impact, contact, dq = np.append(normal, restitution), terms.contact_terms, terms.dq
    if name == "crb":
        motion = crb_cycle_update(contact, terms.com, terms.inertia_com, terms.mass, dq, impact, out)
    elif name == "gm":
        motion = gm_cycle_update(terms.M_inv, contact, dq, impact, out)
    else:
        motion = classical_cycle_update(terms.M_inv, contact, dq, impact, out)
    matrices, reference_motion = reference_fixed_base_cycle_update(model, terms, normal, restitution)
    flat = np.concatenate([np.ravel(reference) for reference in matrices[:3]])
    np.testing.assert_allclose(out, flat, rtol=0.0, atol=1e-12 * np.abs(flat).max())
    for fast, reference in zip(fixed_base_matrix_views(out, JOINTS), matrices[:3]):
        np.testing.assert_allclose(fast, reference, rtol=0.0, atol=1e-12 * np.abs(reference).max())
    np.testing.assert_allclose(motion, reference_motion, rtol=1e-10, atol=1e-12)
