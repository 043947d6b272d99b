"""The frictional impact integrated by a generic ODE solver (scipy's ``solve_ivp``, DOP853, with
its own event location), independently of ``controller.model.frictional_impact``: the same
equations (du = W dP over the normal impulse p, Coulomb slip, stick, reversal, energetic or
kinematic restitution), every phase integrated numerically, the invariant ray found by Brent's
method."""

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

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


def reference_impact(W, n, v, mu, e, model):
    """(impulse, post-impact velocity, mode) of the impact, every phase by ``solve_ivp``."""
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

    def rhs(_, z, rate):
        if rate is None:
            s = z[:2] / np.linalg.norm(z[:2])
            rate = -mu * s
        force = np.array([rate[0], rate[1], 1.0])
        return np.concatenate([Wc @ force, rate, [z[2]]])

    for _ in range(6):
        events = []

        def compressed(_, z, *args):
            return z[2]

        def ended(_, z, *args):
            return z[5] - target if model == "energetic" else z[2] - target

        def stop(_, z, *args):
            return np.linalg.norm(z[:2]) - stopped

        for event in (compressed if compression is None else ended,) + ((stop,) if rate_t is None else ()):
            event.terminal = True
            events.append(event)
        solution = solve_ivp(rhs, (p, p + 20 * scale), y, method="DOP853", events=events, args=(rate_t,),
                             max_step=scale / 100, **TOLERANCES)
        fired = [k for k, times in enumerate(solution.t_events) if len(times)]
        k = min(fired, key=lambda k: solution.t_events[k][0])
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
    return R @ np.array([y[3], y[4], p]), R @ y[:3], mode
