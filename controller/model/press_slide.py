"""The press that follows an impact when the arm's command keeps moving into the surface: the
steady contact of a joint-impedance-held arm whose reference goes on at a constant Cartesian
velocity, sticking or sliding (docs/frictional-impacts.md, "The press after the impact").

An impact law (``frictional_impact``) ends with the compression: n^T v+ = 0. An arm whose
reference keeps going into the surface (a plain approach that never stops) does not separate
then: its joint impedance presses the tool with a growing force, and the contact point moves
along the surface at a speed the press sets, not the impact. Quasi-statically (the arm's inertia
negligible against the impedance over the press's tens of milliseconds), the drive's torque
K (q_ref - q) + D (dq_ref - dq) balances the surface's force f on the robot, J^T f (J the
contact point's translation Jacobian, K = diag(K_i)); with the force growing at a constant rate
(the deflection's rate constant, so D's share constant), the rates balance:

    K (dq_ref - dq) = -J^T f',   so   dq = dq_ref + K^-1 J^T f',   v = v_ref + C f',

v_ref = J dq_ref the reference's contact velocity (the command's) and C = J K^-1 J^T
(:func:`contact_compliance`) the contact's compliance through the joints. The contact stays on
the surface, n^T v = 0, with Coulomb friction mu:

- **stick**: v = 0, so f' = -C^-1 v_ref, held when f'_n > 0 and |f'_t| <= mu f'_n;
- **slide** along the unit tangent s: the force on the cone's edge opposing the slide, f' =
  f'_n (n - mu s), so f'_n = -n^T v_ref / (n^T C (n - mu s)) > 0 and the tangential velocity
  v_t = (I - n n^T)(v_ref + f'_n C (n - mu s)) = lambda s, lambda > 0.

The slide's direction s is found as ``frictional_impact.reversal_direction`` finds a slip from
rest: the cross product of s(theta) with v_t(s(theta)) changes sign at each consistent direction;
of those with lambda > 0 and f'_n > 0, the one with the largest lambda. The stick is taken when
it holds. Coulomb's rate problem need not have one solution: in a few random states in a
thousand (large mu, soft joints), a stick and a slide both hold, or two slides do; the model then
takes the stick, else the faster slide, where the arm's dynamics (which this quasi-static model
leaves out) decides which one it reaches. With mu = 0 the force grows along n only; with v_ref
along -n the slide is the coupling's, C's tangential response to the normal force, the press's
counterpart of a reversal from rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import validation
from .frictional_impact import RAY_ANGLES, contact_frame, fastest_ray
from .impedance_inverse_inertia import joint_impedance
from .model_terms import ModelTerms
from .validation import BadInputError

SLIDE_ANGLES = 4 * RAY_ANGLES
"""The directions scanned for a slide's sign changes (a quarter of a degree apart: two slides
closer than that, near the stick's boundary, can be missed)."""


@dataclass(frozen=True)
class PressSlide:
    """The steady press of the module docstring (world frame): its ``mode`` ("stick" or
    "slide"), the contact velocity ``velocity`` (v, tangential: n^T v = 0; zero for a stick), the
    surface's force rate on the robot ``force_rate`` (f', N/s) and the slide's unit direction
    ``direction`` (zero for a stick)."""

    mode: str
    velocity: np.ndarray
    force_rate: np.ndarray
    direction: np.ndarray


def contact_compliance(terms: ModelTerms, stiffness) -> np.ndarray:
    """C = J K^-1 J^T (3 x 3, m/N): the contact point's displacement per unit force through the
    joints held by the stiffnesses ``stiffness`` (N m/rad, one > 0 per joint) at the state of
    ``terms``."""
    stiffness = joint_impedance(stiffness, terms.J.shape[1])
    if not np.all(stiffness > 0.0):
        raise BadInputError(f"a press needs every joint's stiffness > 0 N m/rad, got {stiffness.tolist()}")
    return (terms.J / stiffness) @ terms.J.T


def press_slide(compliance: np.ndarray, normal, reference_velocity, friction: float) -> PressSlide:
    """The steady press (module docstring) of the contact of compliance C = ``compliance``
    (3 x 3, symmetric positive definite) on the surface of unit normal n = ``normal`` (towards
    the robot), the reference moving the contact point at v_ref = ``reference_velocity`` (m/s,
    into the surface: n^T v_ref < 0), Coulomb coefficient mu = ``friction``."""
    n = validation.unit_normal(normal)
    v_ref = validation.finite_vector(reference_velocity, 3, "the reference's contact velocity")
    mu = validation.number_in_range(friction, 0.0, 10.0, "the friction coefficient", "")
    C = np.asarray(compliance, dtype=float)
    if C.shape != (3, 3) or not np.all(np.isfinite(C)):
        raise BadInputError(f"the contact's compliance must be a finite 3 x 3 matrix, got shape {C.shape}")
    R = contact_frame(n)
    Cc, a = R.T @ (0.5 * (C + C.T)) @ R, R.T @ v_ref
    if not a[2] < 0.0:
        raise BadInputError(f"a press needs the reference moving into the surface: n^T v_ref = {a[2]:.6g} m/s must be < 0")
    held = np.linalg.solve(Cc, -a)  # f' of a stick, contact frame
    if held[2] > 0.0 and math.hypot(held[0], held[1]) <= mu * held[2]:
        return PressSlide("stick", np.zeros(3), R @ held, np.zeros(3))
    s = slide_direction(Cc, a, mu)
    rate = -a[2] / (Cc[2, 2] - mu * Cc[2, :2] @ s)
    force_rate = rate * np.array([-mu * s[0], -mu * s[1], 1.0])
    u = a + Cc @ force_rate
    u[2] = 0.0  # n^T v = 0 by the choice of f'_n; exactly
    return PressSlide("slide", R @ u, R @ force_rate, R @ np.array([s[0], s[1], 0.0]))


def slide_direction(Cc: np.ndarray, a: np.ndarray, mu: float) -> np.ndarray:
    """s (unit, the contact frame's tangent plane) of a slide (module docstring): for the
    compliance ``Cc`` and reference velocity ``a`` in the contact frame (t1, t2, n), the
    direction with v_t(s) = lambda s, lambda > 0, f'_n > 0; of several, the largest lambda."""

    def ray(theta):
        s = np.array([math.cos(theta), math.sin(theta)])
        denominator = Cc[2, 2] - mu * Cc[2, :2] @ s
        if denominator <= 0.0:
            return math.nan, -math.inf  # no pressing force slides this way
        rate = -a[2] / denominator
        v_t = a[:2] + rate * (Cc[:2, 2] - mu * Cc[:2, :2] @ s)
        return s[0] * v_t[1] - s[1] * v_t[0], float(s @ v_t)

    best = fastest_ray(ray, SLIDE_ANGLES)
    if best is None:
        raise ArithmeticError(f"no steady press: no stick, and no slide among {SLIDE_ANGLES} directions")
    return best
