"""The fixed base's per-cycle impact kernels (``constraints.impact_cycle_kernels``) against their
numpy statements (``tests/reference/constraints.py``), over random states."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.constraints import reference_fixed_base_cycle_update, reference_normal_motion

from conftest import JOINTS, random_state
from impactqp.constraints.impact_cycle_kernels import (
    CLASSICAL,
    CRB,
    GM,
    RULE_VALUES,
    activation,
    classical_cycle_update,
    crb_cycle_update,
    stacked_updates,
    symmetric_positive_inverse,
    fixed_base_matrix_views,
    gm_cycle_update,
    normal_motion,
)
from impactqp.controller.model.friction_pyramid import edge_matrices_into
from impactqp.controller.model.jump import gm_inverse_inertia, jump_model
from impactqp.controller.model.jump_kernels import welded_inverse_inertia

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


@settings(max_examples=200, deadline=None)
@given(
    always=st.booleans(), release=st.floats(0.0, 1.0), distance=st.floats(0.0, 1.0), time=st.floats(0.0, 10.0),
    offset=st.floats(-1.0, 1.0), speed=st.floats(-2.0, 2.0), position=st.floats(-2.0, 2.0),
)
def test_the_compiled_activation_rule_is_the_rule_of_the_docstring(always, release, distance, time, offset, speed,
                                                                   position):
    """On when always active, else when the contact does not leave (n.v <= release speed) and the
    surface is near (n.p - n.s within the look-ahead distance, or within the look-ahead time at -n.v)."""
    rule = np.array([0.0, 0.0, 1.0, 0.0, float(always), release, distance, time, offset, CRB])
    near = position - offset <= distance or position - offset <= -speed * time
    assert activation(rule, speed, position) == (always or (speed <= release and near))


@settings(max_examples=40, deadline=None)
@given(seed=SEEDS, models=st.lists(st.sampled_from([CRB, GM, CLASSICAL]), min_size=1, max_size=3),
       edges=st.sampled_from([0, 3, 4, 8]))
def test_a_plans_impact_updates_are_each_impacts_own_fill(robot, seed, models, edges):
    """``stacked_updates`` writes, for each of several impacts (crb, gm or classical; normals,
    restitutions, rules, edge directions), its row [A, P, G, the edges' A_i and P_i, activation]
    as its model's kernel, ``edge_matrices_into`` with its W and ``activation`` do alone at the
    terms' M^-1 (to 1e-12 of the largest entry: M^-1 by another Cholesky, the same kernels
    compiled into different callers)."""
    rng = np.random.default_rng(seed)
    terms = random_state(robot, rng)
    rules = np.empty((len(models), RULE_VALUES + 3 * edges))
    for rule, model in zip(rules, models):
        normal = rng.normal(size=3)
        rule[:3], rule[3] = normal / np.linalg.norm(normal), rng.uniform(0.0, 1.0)
        rule[4:9] = rng.random() < 0.3, rng.uniform(0.0, 0.1), rng.uniform(0.0, 0.2), rng.uniform(0.0, 1.0), rng.normal()
        rule[9] = model
        directions = rng.normal(size=(edges, 3))
        rule[10:] = np.ravel(directions / np.linalg.norm(directions, axis=1, keepdims=True)) if edges else []
    square = JOINTS * JOINTS
    rows = np.full((len(models), (3 + 2 * edges) * square + 1), np.nan)
    stacked_updates(terms.contact_terms, terms.dq, terms.locked_body, terms.M, rules, rows)
    contact, dq, M_inv = terms.contact_terms, terms.dq, terms.M_inv
    for rule, row, model in zip(rules, rows, models):
        out = np.empty(2 * square + 9)
        if model == CRB:
            motion = crb_cycle_update(contact, terms.com, terms.inertia_com, terms.mass, dq, rule[:4], out)
            W = welded_inverse_inertia(terms.contact_point, terms.com, terms.inertia_com, terms.mass)
        else:
            update = gm_cycle_update if model == GM else classical_cycle_update
            motion = update(M_inv, contact, dq, rule[:4], out)
            W = gm_inverse_inertia(terms)
        np.testing.assert_allclose(row[:out.shape[0]], out, rtol=0.0, atol=1e-12 * np.abs(out).max())
        if edges:
            edge_maps = np.empty((2, edges, JOINTS, JOINTS))
            classical = M_inv if model == CLASSICAL else np.empty((0, 0))
            edge_matrices_into(terms.J, terms.JJt_inv, classical, W, rule[10:].reshape(edges, 3), rule[:3], rule[3], edge_maps)
            np.testing.assert_allclose(row[3 * square:-1], np.ravel(edge_maps), rtol=0.0, atol=1e-12 * np.abs(edge_maps).max())
        assert row[-1] == float(activation(rule, *motion))


def test_a_matrix_that_is_not_positive_definite_has_a_nan_inverse():
    """``symmetric_positive_inverse`` of an SPD matrix is its inverse; of an indefinite one, NaN
    (which the solution's check refuses downstream)."""
    A = np.random.default_rng(1).normal(size=(5, 5))
    S = A @ A.T + np.eye(5)
    np.testing.assert_allclose(symmetric_positive_inverse(S) @ S, np.eye(5), atol=1e-10)
    assert np.all(np.isnan(symmetric_positive_inverse(S - 20.0 * np.eye(5))))
