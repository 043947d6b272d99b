"""The inverse inertia at the contact of an arm held by a joint impedance over an impact of
duration T (docs/frictional-impacts.md, "The held arm's W from the model").

The predictors' W are limits: W_gm = J M^-1 J^T (eq. 22) the joints free over the impact, W_crb
(eq. 20) the joints locked on a floating body. A joint impedance (a Franka's drives) holds each
joint by its own stiffness K_i and damping D_i while the impact lasts, so the contact point's
velocity change per unit impulse depends on the impact's duration.

The arm linearised about its posture q0, at rest, the servo's gravity and Coriolis
compensation h(q, dq) cancelling the plant's (``sim.servo.JointImpedanceServo``: tau = K (q0 - q)
- D dq + h), the joint displacement x = q - q0 obeys

    M x'' + D x' + K x = J^T f(t),   x(0) = x'(0) = 0,

M = M(q0), K = diag(K_i), D = diag(D_i) with the servo's critical damping D_i = 2 sqrt(K_i
M_ii) (:func:`critical_damping`), J = J(q0) the contact point's translation Jacobian. The impulse
iota is spread as the oblique study's pulse, a half-sine of duration T:

    f(t) = iota g(t),   g(t) = pi / (2 T) sin(pi t / T),   int_0^T g = 1.

The joint velocity at the pulse's end is x'(T) = Phi(T) J^T iota, and the contact velocity's
change per unit impulse is

    W_K(T) = J Phi(T) J^T.

Phi (n x n) is the exact solution of the linear system (:func:`held_velocity_response`): with the
state X = [x; x'] (2n x n, one column per unit generalised impulse), A = [[0, I], [-M^-1 K,
-M^-1 D]], B = [0; M^-1], and the forcing's own linear state S = sin(w t) I, C = cos(w t) I (w =
pi / T: S' = w C, C' = -w S), the augmented system Z' = E Z, Z = [X; S; C], is autonomous:

    E = [[A, pi / (2 T) B, 0], [0, 0, w I], [0, -w I, 0]],   Z(0) = [0; 0; I],

so Z(T) = expm(E T) Z(0) (``scipy.linalg.expm``, Pade with scaling and squaring, on a 4n x 4n
matrix) and Phi(T) is X(T)'s velocity block. Chosen over a modal decomposition because a
diagonal D is not a combination of M and K (the modes do not decouple) and because it stays exact
for any K, D, T, including K = D = 0: then Phi(T) = M^-1 int_0^T g = M^-1 and W_K = J M^-1 J^T =
W_gm. As T -> 0 the impedance has no time to act and W_K -> W_gm too; as T grows it holds the
joints and W_K shrinks (the held arm does not move its base, unlike CRB's floating body).

Phi(T) is symmetric: the velocity response's transfer function s (M s^2 + D s + K)^-1 is, M, D,
K being symmetric. It stays positive definite while T is short against the held arm's slowest
period (the impulse has not been undone yet: a stiff servo over a long pulse turns the contact
point back, n^T W n < 0).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from .model_terms import ModelTerms
from .validation import BadInputError


def joint_impedance(values, joints: int) -> np.ndarray:
    """``values`` as one finite number >= 0 per joint (bad input otherwise)."""
    values = np.asarray(values, dtype=float)
    if values.shape != (joints,) or not np.all(np.isfinite(values) & (values >= 0.0)):
        raise BadInputError(f"a joint impedance needs {joints} finite numbers >= 0, got {values.tolist()}")
    return values


def critical_damping(stiffness: np.ndarray, M: np.ndarray) -> np.ndarray:
    """D_i = 2 sqrt(K_i M_ii): each joint's impedance critically damped on its own inertia (the
    servo's, ``sim.servo.JointImpedanceServo``)."""
    return 2.0 * np.sqrt(stiffness * np.diag(M))


def held_velocity_response(M: np.ndarray, stiffness: np.ndarray, damping: np.ndarray, duration: float) -> np.ndarray:
    """Phi(T) (n x n): the joint velocity at the end of a half-sine pulse of duration T =
    ``duration`` per unit generalised impulse, the joints held by the diagonal impedance K =
    ``stiffness``, D = ``damping`` about the posture of inertia M (module docstring)."""
    n = M.shape[0]
    stiffness, damping = joint_impedance(stiffness, n), joint_impedance(damping, n)
    if not (np.isfinite(duration) and duration > 0.0):
        raise BadInputError(f"the pulse's duration T = {duration} s must be > 0")
    M_inv = np.linalg.inv(M)
    w = np.pi / duration
    E = np.zeros((4 * n, 4 * n))
    position, velocity, sine, cosine = (slice(k * n, (k + 1) * n) for k in range(4))
    E[position, velocity] = np.eye(n)
    E[velocity, position] = -M_inv * stiffness  # -M^-1 K (K diagonal: scales M^-1's columns)
    E[velocity, velocity] = -M_inv * damping
    E[velocity, sine] = 0.5 * w * M_inv  # pi / (2 T) M^-1 S
    E[sine, cosine] = w * np.eye(n)
    E[cosine, sine] = -w * np.eye(n)
    return expm(E * duration)[velocity, cosine]  # Z(0) = [0; 0; I]: the column block of C


def impedance_inverse_inertia(terms: ModelTerms, stiffness, duration: float) -> np.ndarray:
    """W_K(T) = J Phi(T) J^T (3 x 3): the contact point's velocity change per unit impulse spread
    over a half-sine of duration T = ``duration``, the arm of ``terms`` (at rest) held by the
    critically damped joint impedance of ``stiffness`` (N m/rad per joint; module docstring)."""
    stiffness = joint_impedance(stiffness, terms.M.shape[0])
    Phi = held_velocity_response(terms.M, stiffness, critical_damping(stiffness, terms.M), duration)
    return terms.J @ Phi @ terms.J.T
