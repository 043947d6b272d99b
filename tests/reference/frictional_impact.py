"""The frictional impact integrated by a generic ODE solver (scipy's ``solve_ivp``, DOP853, with
its own event location), independently of ``controller.model.frictional_impact``: the same
equations (du = W dP over the normal impulse p, Coulomb slip, stick, reversal, energetic or
kinematic restitution), every phase integrated numerically, the invariant ray found by Brent's
method."""

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

TOLERANCES = {"rtol": 1e-12, "atol": 1e-15}


def frame(n):
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1)
    return np.column_stack([t1, np.cross(n, t1), n])


def invariant_ray(Wc, mu):
    """The unit s with W_tn - mu W_tt s = lambda s, lambda > 0 largest."""

    def cross(theta):
        s = np.array([math.cos(theta), math.sin(theta)])
        g = Wc[:2, 2] - mu * Wc[:2, :2] @ s
        return s[0] * g[1] - s[1] * g[0]

    best, rate = None, 0.0
    grid = np.linspace(0.0, 2 * math.pi, 2001)
    for a, b in zip(grid[:-1], grid[1:]):
        if cross(a) * cross(b) <= 0.0:
            theta = brentq(cross, a, b, xtol=1e-15) if cross(a) != cross(b) else a
            s = np.array([math.cos(theta), math.sin(theta)])
            lam = s @ (Wc[:2, 2] - mu * Wc[:2, :2] @ s)
            if lam > rate:
                best, rate = s, lam
    return best


def reference_impact(W, n, v, mu, e, model, with_least_speed=False):
    """(impulse, post-impact velocity, mode) of the impact, every phase by ``solve_ivp``; with
    ``with_least_speed`` also the smallest tangential speed |u_t| along it (each phase's dense
    output on a grid of 2,000 points, the grid's least refined by a bounded scalar search)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    R = frame(n)
    Wc = R.T @ W @ R
    u0 = R.T @ np.asarray(v, float)
    scale = (1 + e) * -u0[2] / Wc[2, 2]
    stopped = 1e-9 * np.linalg.norm(u0)
    y = np.concatenate([u0, np.zeros(3)])  # u (3), P_t (2), work of the normal impulse in the phase
    p = 0.0
    d = -np.linalg.solve(Wc[:2, :2], Wc[:2, 2])
    if mu == 0.0:
        mode, rate_t = "frictionless", np.zeros(2)
    elif np.linalg.norm(u0[:2]) > stopped:
        mode, rate_t = "slip", None
    elif np.linalg.norm(d) <= mu:
        mode, rate_t = "stick", d
    else:
        mode, rate_t = "reversal", -mu * invariant_ray(Wc, mu)
    compression, target = None, None
    least = np.linalg.norm(u0[:2])

    def rhs(_, z, rate):
        if rate is None:
            speed = math.hypot(z[0], z[1])
            r0, r1 = -mu * z[0] / speed, -mu * z[1] / speed
        else:
            r0, r1 = rate
        out = np.empty(6)
        out[:3] = Wc[:, 0] * r0 + Wc[:, 1] * r1 + Wc[:, 2]
        out[3], out[4], out[5] = r0, r1, z[2]
        return out

    for _ in range(6):
        events = []

        def compressed(_, z, *args):
            return z[2]

        def ended(_, z, *args):
            return z[5] - target if model == "energetic" else z[2] - target

        def stop(_, z, *args):
            return math.hypot(z[0], z[1]) - stopped

        for event in (compressed if compression is None else ended,) + ((stop,) if rate_t is None else ()):
            event.terminal = True
            events.append(event)
        solution = solve_ivp(rhs, (p, p + 20 * scale), y, method="DOP853", events=events, args=(rate_t,),
                             max_step=scale / 10, dense_output=with_least_speed, **TOLERANCES)
        fired = [k for k, times in enumerate(solution.t_events) if len(times)]
        k = min(fired, key=lambda k: solution.t_events[k][0])
        if with_least_speed:
            least = min(least, phase_least_speed(solution.sol, p, solution.t_events[k][0]))
        p, y = solution.t_events[k][0], solution.y_events[k][0].copy()
        if rate_t is None and k == 1:  # slip stopped
            y[:2] = 0.0
            if np.linalg.norm(d) <= mu:
                mode, rate_t = "stick", d
            else:
                mode, rate_t = "reversal", -mu * invariant_ray(Wc, mu)
            continue
        if compression is None:
            compression = p
            target = -e * e * y[5] if model == "energetic" else -e * u0[2]  # restitution's work, final u_n
            y[2], y[5] = 0.0, 0.0  # compression ends exactly; restitution's work starts from 0
            if e == 0.0:
                break
            continue
        break
    if with_least_speed:
        return R @ np.array([y[3], y[4], p]), R @ y[:3], mode, least
    return R @ np.array([y[3], y[4], p]), R @ y[:3], mode


def phase_least_speed(path, start, end):
    """The least |u_t| of a dense ODE solution ``path`` over the normal impulse [start, end]."""
    grid = np.linspace(start, end, 2001)
    speeds = np.hypot(*path(grid)[:2])
    k = int(np.argmin(speeds))
    low, high = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    refined = minimize_scalar(lambda x: np.hypot(*path(x)[:2]), bounds=(low, high), method="bounded",
                              options={"xatol": 1e-14 * max(abs(end), 1e-300)})
    return min(float(speeds[k]), float(refined.fun))
