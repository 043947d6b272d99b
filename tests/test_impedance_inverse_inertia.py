"""First-principles checks of the held arm's inverse inertia W_K(T) = J Phi(T) J^T
(controller/model/impedance_inverse_inertia.py): its limits (no impedance, T -> 0), its symmetry
and positive definiteness, and Phi against a generic integration of the same linear system."""

import numpy as np
import pytest
import scipy.linalg
from conftest import joint_positions
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from impactqp.controller.model.impedance_inverse_inertia import (
    critical_damping,
    held_velocity_response,
    impedance_inverse_inertia,
)
from impactqp.controller.model.jump import gm_inverse_inertia
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, SingularPostureError
from impactqp.controller.model.validation import BadInputError

ROBOT = PandaModel()
FRANKA_STIFFNESS = np.array((3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0))
"""N m/rad: a Franka's default joint impedance (libfranka's examples)."""
SETTINGS = settings(max_examples=25, deadline=None)
durations = st.floats(1e-4, 0.05)
stiffnesses = st.lists(st.floats(0.0, 5000.0), min_size=7, max_size=7).map(np.array)


def terms_at(q):
    """The model terms at q; a singular posture is rejected as an example (hypothesis)."""
    try:
        return ROBOT.terms(q)
    except SingularPostureError:
        reject()


def relative(W, reference):
    return np.linalg.norm(W - reference) / np.linalg.norm(reference)


@SETTINGS
@given(q=joint_positions(), T=durations)
def test_without_an_impedance_the_arm_is_free_over_any_pulse(q, T):
    """K = D = 0: M x'' = J^T f, so x'(T) = M^-1 J^T int_0^T f = M^-1 J^T iota: W_K = J M^-1 J^T."""
    terms = terms_at(q)
    W = impedance_inverse_inertia(terms, np.zeros(7), T)
    np.testing.assert_allclose(W, terms.J @ np.linalg.solve(terms.M, terms.J.T), rtol=0, atol=1e-10 * np.linalg.norm(W))


@SETTINGS
@given(q=joint_positions(), K=stiffnesses)
def test_a_vanishing_pulse_meets_the_free_joints(q, K):
    """T -> 0: the impedance has no time to act, W_K(T) -> W_gm, the distance shrinking with T."""
    terms = terms_at(q)
    W_gm = gm_inverse_inertia(terms)
    distances = [relative(impedance_inverse_inertia(terms, K, T), W_gm) for T in (1e-5, 1e-6, 1e-7)]
    assert distances[2] < 1e-4
    if distances[0] > 1e-9:  # above rounding: the distance is O(T)
        assert distances[1] < 0.2 * distances[0] and distances[2] < 0.2 * distances[1]


@SETTINGS
@given(q=joint_positions(), K=stiffnesses, share=st.floats(0.01, 1.0))
def test_the_held_arms_W_is_symmetric_positive_definite_within_its_fastest_period(q, K, share):
    """Phi(T) is symmetric (s (M s^2 + D s + K)^-1 is); positive definite, and so W_K with J of
    rank 3, while the pulse is short against the held arm's fastest mode: T omega_max <= 2,
    omega_max^2 the largest eigenvalue of M^-1 K (one critically damped joint turns back at
    omega T = 2.63)."""
    terms = terms_at(q)
    omega_max = np.sqrt(max(scipy.linalg.eigh(np.diag(K), terms.M, eigvals_only=True).max(), 1.0))
    T = share * 2.0 / omega_max
    Phi = held_velocity_response(terms.M, K, critical_damping(K, terms.M), T)
    W = impedance_inverse_inertia(terms, K, T)
    for matrix in (Phi, W):
        np.testing.assert_allclose(matrix, matrix.T, rtol=0, atol=1e-12 * np.linalg.norm(matrix))
        assert np.linalg.eigvalsh(matrix).min() > 0.0


def test_one_critically_damped_joint_turns_back_after_its_period():
    """One joint, K = omega^2 m, D = 2 omega m: x'(T) > 0 at omega T = 2, < 0 at omega T = 3 (the
    impedance has undone the pulse: why positive definiteness needs a short pulse)."""
    m, omega = 0.5, 300.0
    for ratio, sign in ((2.0, 1.0), (3.0, -1.0)):
        Phi = held_velocity_response(np.array([[m]]), np.array([omega**2 * m]), np.array([2 * omega * m]), ratio / omega)
        assert sign * Phi[0, 0] > 0.0


@settings(max_examples=8, deadline=None)
@given(q=joint_positions(), K=stiffnesses, D_share=st.floats(0.0, 2.0), T=st.floats(1e-3, 0.02))
def test_phi_is_the_linear_systems_velocity_at_the_pulses_end(q, K, D_share, T):
    """Against scipy's DOP853 (rtol 1e-12) on M x'' + D x' + K x = u g(t), g(t) = pi / (2 T)
    sin(pi t / T), from rest, one column of u per joint: Phi(T) to 1e-6 (any diagonal D >= 0)."""
    M, n = terms_at(q).M, 7
    D = D_share * critical_damping(K, M)
    M_inv = np.linalg.inv(M)

    def rate(t, y):
        x, v = y[: n * n].reshape(n, n), y[n * n:].reshape(n, n)
        a = M_inv @ (np.pi / (2 * T) * np.sin(np.pi * t / T) * np.eye(n) - D[:, None] * v - K[:, None] * x)
        return np.concatenate([v.ravel(), a.ravel()])

    solution = solve_ivp(rate, (0.0, T), np.zeros(2 * n * n), method="DOP853", rtol=1e-12, atol=1e-14)
    assert solution.success
    integrated = solution.y[n * n:, -1].reshape(n, n)
    np.testing.assert_allclose(held_velocity_response(M, K, D, T), integrated, rtol=0, atol=1e-6 * np.abs(integrated).max())


@pytest.mark.parametrize("stiffness, T", [(np.ones(6), 0.01), (-FRANKA_STIFFNESS, 0.01), (np.full(7, np.nan), 0.01),
                                          (FRANKA_STIFFNESS, 0.0), (FRANKA_STIFFNESS, np.inf)])
def test_a_bad_impedance_or_pulse_is_bad_input(stiffness, T):
    with pytest.raises(BadInputError):
        impedance_inverse_inertia(ROBOT.terms(PANDA.postures["elbow_right"].q), stiffness, T)
