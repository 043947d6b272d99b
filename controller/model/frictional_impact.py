"""The impulse of a frictional impact in three dimensions, for a given inverse inertia W at the
contact (``docs/frictional-impacts.md``).

The contact velocity u (3) changes with the impulse P on the robot as du = W dP (W: the CRB, GM
or classical inverse inertia of ``controller.model.jump``; 3 x 3, symmetric positive definite).
The impact is integrated over the normal impulse p = n^T P, the independent variable of
Stronge's method (Stronge, "Impact mechanics", ch. 4), in a contact frame (t1, t2, n), n the
surface normal towards the robot, so u_n = n^T u < 0 while the contact closes:

- **slip** (|u_t| > 0): Coulomb friction mu opposes the tangential velocity u_t,
  dP/dp = n - mu s, s = u_t / |u_t|; the tangential velocity follows the autonomous ODE
  du_t/dp = W_tn - mu W_tt s (the phase plane of Jia and Wang for a 3 x 3 W);
- **stick** (u_t = 0): the tangential impulse keeps u_t = 0, dP_t/dp = d = -W_tt^-1 W_tn, which
  Coulomb allows while |d| <= mu; the smallest such mu is the **stick coefficient**
  mu_bar = |W_tt^-1 W_tn| (the seed paper's Sec. VI-B, Stronge eq. 4.12);
- **reversal** (u_t = 0 and |d| > mu): slip resumes along an invariant ray s* of the phase
  plane, W_tn - mu W_tt s* = lambda s* with lambda > 0, and keeps it.

Compression ends at u_n = 0 (normal impulse p_c). Restitution ends, with the **energetic**
coefficient e (Stronge), when the work of the normal impulse during restitution is -e^2 times
its work during compression (int u_n dp over each phase); with the **kinematic** one (Newton),
when u_n = -e u_n(0). Without friction (mu = 0, or no tangential velocity and W_tn = 0), u_n is
linear in p and both give eq. (12): P = -(1 + e) (n^T v-) / (n^T W n) n.

Phases of constant impulse direction (stick, reversal, no friction) are integrated in closed
form; slip over p by a compiled Dormand-Prince 5(4) pair with an adaptive step (each step's
embedded error estimate below :data:`TOLERANCE` of the scales of u, P_t and the work; steps
shorter near u_t = 0, :data:`NEAR_STOP_SHARE`), each event (slip stops, compression ends,
restitution ends) located inside its step by bisection on the step's length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from . import validation
from .validation import BadInputError

RESTITUTION_MODELS = ("energetic", "kinematic")
TOLERANCE = 1e-12
"""The largest error estimate of a slip step, per component of y relative to its scale: |u(0)|
for u, the frictionless impulse (1 + e) |u_n(0)| / W_nn for P_t, their product for the work."""
FIRST_STEP_SHARE = 0.01
"""The first slip step of a phase, as a share of the frictionless impulse."""
MAX_STEPS = 10**7
STOP_SHARE = 1e-9
"""|u_t| below this share of the pre-impact speed is stopped (u_t = 0): above the integration's
own error, so that a trajectory that reaches u_t = 0 is not read as one that passes close by."""
BISECTIONS = 60
"""Halvings of a step's length that locate an event inside it (to 2^-60 of the step)."""
NEAR_STOP_SHARE = 0.05
"""Along slip, a step changes u_t by at most this share of |u_t|: the slip direction turns
fast near u_t = 0, so the steps shrink there (geometrically, towards a stop), and a trajectory
that passes close to u_t = 0 inside one step is not missed by the step's end points."""
RAY_ANGLES = 720
"""Angles scanned for the invariant rays of the slip phase plane (each refined by bisection)."""

# events of the slip kernel, and what ends the phase besides a stop
STOPPED, COMPRESSED, ENDED, NOT_ENDED = 0, 1, 2, 3
COMPRESSING, ENERGETIC, KINEMATIC = 0, 1, 2
# the Dormand-Prince 5(4) pair (Dormand and Prince 1980; Hairer, Norsett and Wanner, "Solving
# ordinary differential equations I", Table II.5.2): the stage rows (the last one the
# fifth-order answer) and the error weights E = b5 - b4 of the embedded fourth-order answer
DP_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0],
    [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
])
DP_ERROR = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])


@dataclass(frozen=True)
class FrictionalImpact:
    """The answer of :func:`frictional_impulse`: the impulse on the robot ``impulse`` (3, in the
    frame of W), the contact velocity after the impact ``post_velocity``, the ``mode`` of the
    contact ("slip": slid throughout; "stick": stopped sliding and stuck; "reversal": stopped,
    then slid along a new direction; "frictionless": mu = 0), the stick coefficient ``mu_bar``,
    the normal impulse at the end of compression ``compression_impulse`` and the smallest
    tangential contact speed |u_t| along the impact ``least_tangential_speed`` (0 once the slip
    stops; along slip, at the start and the ends of the integration's steps, each of which
    changes u_t by at most :data:`NEAR_STOP_SHARE` |u_t|; along a phase of constant impulse
    direction, u_t is linear in p: the segment's distance to 0)."""

    impulse: np.ndarray
    post_velocity: np.ndarray
    mode: str
    mu_bar: float
    compression_impulse: float
    least_tangential_speed: float


def contact_frame(normal: np.ndarray) -> np.ndarray:
    """R = [t1 t2 n] (columns): an orthonormal frame whose third axis is the unit normal n."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(helper, normal)
    t1 /= np.linalg.norm(t1)
    return np.column_stack([t1, np.cross(normal, t1), normal])


def stick_direction(Wc: np.ndarray) -> np.ndarray:
    """d = -W_tt^-1 W_tn (W in the contact frame): the tangential impulse per unit normal
    impulse that keeps u_t = 0."""
    return -np.linalg.solve(Wc[:2, :2], Wc[:2, 2])


def reversal_direction(Wc: np.ndarray, mu: float) -> np.ndarray:
    """s* (unit, contact frame) with W_tn - mu W_tt s* = lambda s*, lambda > 0: where slip goes
    once sticking needs more than mu. The cross product of s(theta) with
    g(theta) = W_tn - mu W_tt s(theta) changes sign at each invariant ray; of the rays with
    lambda = s . g > 0, the one with the largest lambda."""

    def ray(theta):
        s = np.array([math.cos(theta), math.sin(theta)])
        g = Wc[:2, 2] - mu * Wc[:2, :2] @ s
        return s[0] * g[1] - s[1] * g[0], float(s @ g)

    best = fastest_ray(ray, RAY_ANGLES)
    if best is None:
        raise ArithmeticError("no invariant slip ray leaves the origin: W is not an inverse inertia")
    return best


def fastest_ray(ray, angles: int) -> np.ndarray | None:
    """The unit s(theta) = (cos theta, sin theta) of the fastest invariant ray of a planar map:
    ``ray(theta)`` gives (s x g, s . g) for the map's value g along s. Each sign change of s x g
    between ``angles`` evenly spaced angles is refined by BISECTIONS bisections; of the rays found,
    the one with the largest s . g > 0. None when there is none. A side where ``ray`` gives NaN
    (no ray there) has no sign change."""
    thetas = np.linspace(0.0, 2.0 * math.pi, angles + 1)
    crosses = [ray(theta)[0] for theta in thetas]
    best, best_rate = None, 0.0
    for k in range(angles):
        if not crosses[k] * crosses[k + 1] <= 0.0:
            continue
        low, high = thetas[k], thetas[k + 1]
        for _ in range(BISECTIONS):
            middle = 0.5 * (low + high)
            if ray(low)[0] * ray(middle)[0] <= 0.0:
                high = middle
            else:
                low = middle
        rate = ray(0.5 * (low + high))[1]
        if rate > best_rate:
            best, best_rate = 0.5 * (low + high), rate
    return None if best is None else np.array([math.cos(best), math.sin(best)])


def frictional_impulse(
    W: np.ndarray,
    normal,
    pre_velocity,
    friction: float,
    restitution: float = 0.0,
    restitution_model: str = "energetic",
) -> FrictionalImpact:
    """The frictional impact of the module docstring for the inverse inertia W (3 x 3), the
    surface normal n (towards the robot), the pre-impact contact velocity v- (with n^T v- < 0),
    the Coulomb coefficient mu >= 0, the restitution e in [0, 1] and its model (energetic or
    kinematic); every vector in the frame of W."""
    n = validation.unit_normal(normal)
    v = validation.finite_vector(pre_velocity, 3, "the pre-impact contact velocity")
    e = validation.restitution(restitution)
    mu = validation.number_in_range(friction, 0.0, 10.0, "the friction coefficient", "")
    validation.name_in(restitution_model, RESTITUTION_MODELS, "the restitution model")
    W = np.asarray(W, dtype=float)
    if W.shape != (3, 3) or not np.all(np.isfinite(W)):
        raise BadInputError(f"W must be a finite 3 x 3 matrix, got shape {W.shape}")
    R = contact_frame(n)
    Wc = R.T @ (0.5 * (W + W.T)) @ R
    u0 = R.T @ v
    if not u0[2] < 0.0:
        raise BadInputError(f"the contact does not approach the surface: n^T v- = {u0[2]:.6g} m/s must be < 0")
    energetic = restitution_model == "energetic"
    # y = (u_t1, u_t2, u_n, P_t1, P_t2, work of the normal impulse in the current phase of the
    # impact: compression, then restitution), p the normal impulse
    y, p = np.concatenate([u0, np.zeros(3)]), 0.0
    speed, impulse_scale = float(np.linalg.norm(u0)), (1.0 + e) * -u0[2] / Wc[2, 2]
    stopped = STOP_SHARE * speed
    scale = np.array([speed, speed, speed, impulse_scale, impulse_scale, speed * impulse_scale])
    mu_bar = float(np.linalg.norm(stick_direction(Wc)))
    if mu == 0.0:
        mode, direction = "frictionless", np.zeros(2)
    elif math.hypot(u0[0], u0[1]) > stopped:
        mode, direction = "slip", None
    else:
        mode, direction = after_stop(Wc, mu, mu_bar)
    compression, target = None, 0.0
    least = math.hypot(u0[0], u0[1])
    while True:
        if compression is None and y[2] >= 0.0:
            compression = p
            target = -e * e * y[5] if energetic else -e * u0[2]  # restitution's work or final u_n
            y[5] = 0.0
        if compression is not None and restitution_ended(y, target, energetic):
            break
        if direction is not None:
            start = y[:2].copy()
            p = constant_direction_phase(y, p, Wc, direction, target, energetic, compression is None)
            least = min(least, segment_distance(start, y[:2]))
            if compression is not None:
                break  # the phase ran to the end of restitution (in closed form)
            continue
        ending = COMPRESSING if compression is None else ENERGETIC if energetic else KINEMATIC
        p, event, slowest = slip_phase(Wc, mu, y, p, scale, stopped, target, ending)
        least = min(least, slowest)
        if event == ENDED:
            break
        if event == STOPPED:
            y[:2] = 0.0
            least = 0.0
            mode, direction = after_stop(Wc, mu, mu_bar)
    impulse = np.array([y[3], y[4], p])
    # v+ = v- + W P: the integrated u agrees to the stop threshold (u_t set to 0 at a stop)
    return FrictionalImpact(R @ impulse, R @ (u0 + Wc @ impulse), mode, mu_bar, float(compression), float(least))


def segment_distance(start: np.ndarray, end: np.ndarray) -> float:
    """The distance from 0 of the segment from ``start`` to ``end`` (vectors of equal size)."""
    step = end - start
    length = float(step @ step)
    share = 0.0 if length == 0.0 else min(max(-float(start @ step) / length, 0.0), 1.0)
    return float(np.linalg.norm(start + share * step))


def after_stop(Wc: np.ndarray, mu: float, mu_bar: float) -> tuple[str, np.ndarray]:
    """The mode and the tangential impulse rate dP_t/dp once u_t = 0: stick (d) when
    mu >= mu_bar, else reversal along the invariant ray (-mu s*)."""
    if mu >= mu_bar:
        return "stick", stick_direction(Wc)
    return "reversal", -mu * reversal_direction(Wc, mu)


@njit(cache=True)
def restitution_ended(y, target, energetic) -> bool:
    """Whether restitution has ended (past compression): the work of the normal impulse since
    compression ended has reached ``target`` (energetic) or u_n has reached it (kinematic)."""
    if energetic:
        return y[2] >= 0.0 and y[5] >= target - 1e-15 * abs(target)
    return y[2] >= target - 1e-15 * abs(target)


def constant_direction_phase(y, p, Wc, direction, target, energetic, compressing) -> float:
    """Advance y in place along dP = (direction, 1) dp, in closed form (u linear in p, the work
    quadratic): to the end of compression (u_n = 0) when compressing, else to the end of
    restitution; returns the new p."""
    rate = Wc @ np.array([direction[0], direction[1], 1.0])
    un, a = y[2], rate[2]
    if a <= 0.0:
        raise ArithmeticError("the normal velocity does not grow with the impulse: W is not an inverse inertia")
    if compressing:
        dp = -un / a
    elif not energetic:
        dp = max((target - un) / a, 0.0)
    else:
        remaining = max(target - y[5], 0.0)  # work + un dp + a dp^2 / 2 = target, un >= 0
        dp = (-un + math.sqrt(un * un + 2.0 * a * remaining)) / a
    y[5] += un * dp + 0.5 * a * dp * dp
    y[:3] += rate * dp
    if compressing:
        y[2] = 0.0
    y[3:5] += direction * dp
    return p + dp


@njit(cache=True)
def slip_rate(Wc, mu, y, out):
    """dy/dp along slip: du = W (n - mu s) dp, dP_t = -mu s dp, d work = u_n dp."""
    norm = math.sqrt(y[0] * y[0] + y[1] * y[1])
    f0, f1 = -mu * y[0] / norm, -mu * y[1] / norm
    for i in range(3):
        out[i] = Wc[i, 0] * f0 + Wc[i, 1] * f1 + Wc[i, 2]
    out[3], out[4], out[5] = f0, f1, y[2]


@njit(cache=True)
def dp_step(Wc, mu, y, h, out, stages, scale) -> float:
    """One step of length h along slip by the Dormand-Prince 5(4) pair, from y into out (its
    fifth-order answer; ``stages`` 7 x 6, the stage rates); returns the step's error estimate
    max_i |h sum_j E_j k_ji| / scale_i (E = b5 - b4), or -1 when the step reaches u_t = 0: a
    stage, or the end, whose tangential velocity points against the start's (the slip
    direction is not defined there; ``slip_phase`` halves the step until it stops short of 0)."""
    for s in range(7):
        for i in range(6):
            total = 0.0
            for j in range(s):
                total += DP_A[s, j] * stages[j, i]
            out[i] = y[i] + h * total
        if s > 0 and out[0] * y[0] + out[1] * y[1] <= 0.0:
            return -1.0
        slip_rate(Wc, mu, out, stages[s])
    error = 0.0
    for i in range(6):
        total = 0.0
        for j in range(7):
            total += DP_ERROR[j] * stages[j, i]
        error = max(error, abs(h * total) / scale[i])
    return error


@njit(cache=True)
def slip_event(z, stopped, target, ending) -> int:
    """The event reached at z: slip stopped (|u_t| <= ``stopped``), compression ended (u_n >= 0,
    ``ending`` COMPRESSING), restitution ended (``ending`` ENERGETIC or KINEMATIC: the work or
    u_n has reached ``target``), or none (NOT_ENDED)."""
    if math.sqrt(z[0] * z[0] + z[1] * z[1]) <= stopped:
        return STOPPED
    if ending == COMPRESSING:
        return COMPRESSED if z[2] >= 0.0 else NOT_ENDED
    return ENDED if restitution_ended(z, target, ending == ENERGETIC) else NOT_ENDED


@njit(cache=True)
def slip_phase(Wc, mu, y, p, scale, stopped, target, ending):
    """Advance y in place along slip up to the first event of ``slip_event``, by Dormand-Prince
    5(4) steps whose error estimate stays below ``TOLERANCE`` (relative to ``scale``, per
    component of y: local extrapolation, the step adapted by the usual factor
    0.9 (TOLERANCE / error)^(1/5)) and that change u_t by at most ``NEAR_STOP_SHARE`` |u_t|;
    the event is located inside its step by bisection on the step's length. Returns the new p,
    the event and the smallest |u_t| at the start and the ends of the steps."""
    z, rate, stages = np.empty(6), np.empty(6), np.empty((7, 6))
    h = FIRST_STEP_SHARE * scale[3]
    least = math.sqrt(y[0] * y[0] + y[1] * y[1])
    for _ in range(MAX_STEPS):
        slip_rate(Wc, mu, y, rate)
        speed = math.sqrt(y[0] * y[0] + y[1] * y[1])
        change = math.sqrt(rate[0] * rate[0] + rate[1] * rate[1])
        step = min(h, NEAR_STOP_SHARE * speed / change) if change > 0.0 else h
        error = dp_step(Wc, mu, y, step, z, stages, scale)
        if error < 0.0:
            h = 0.5 * step
            continue
        h = step * min(5.0, 0.9 * (TOLERANCE / error) ** 0.2) if error > 0.0 else 5.0 * step
        if error > TOLERANCE:
            continue
        event = slip_event(z, stopped, target, ending)
        if event == NOT_ENDED:
            least = min(least, math.sqrt(z[0] * z[0] + z[1] * z[1]))
            y[:] = z
            p += step
            continue
        low, high = 0.0, step
        for _ in range(BISECTIONS):
            middle = 0.5 * (low + high)
            crossed = dp_step(Wc, mu, y, middle, z, stages, scale) < 0.0
            if not crossed and slip_event(z, stopped, target, ending) == NOT_ENDED:
                low = middle
            else:
                high = middle
        dp_step(Wc, mu, y, high, z, stages, scale)  # u_t stays above `stopped` up to low
        event = slip_event(z, stopped, target, ending)
        y[:] = z
        least = min(least, math.sqrt(z[0] * z[0] + z[1] * z[1]))
        if event == STOPPED:
            y[0], y[1] = 0.0, 0.0
        elif event == COMPRESSED:
            y[2] = 0.0
        return p + high, event, least
    raise ArithmeticError("the frictional impact did not end within MAX_STEPS steps")
