"""How well the data bound each fitted parameter: 95 % intervals (``parameter_intervals``).

A Gauss-Newton polish of the joint fit, then per parameter the union of a profile-likelihood
interval (``scan_side``) and a one-step bootstrap over trials (``bootstrap_intervals``; a
bootstrap that reaches a bound of the fit is degenerate and widens nothing); a side
where the profile reaches the fit's bound inside the 95 % region is open (None), and the causes
say which trials would settle it (``open_sides``). Method: ``docs/diagnosis.md``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import t as student_t

from impactqp.sim.causes import FixedParameters
from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import map_in_processes

from .fitting import FittedCauses, cost_of, residual_sizes, residuals
from .trials import MeasuredTrial, ReplaySetting, replay_all

log = logging.getLogger(__name__)

CHI2_95 = 3.841  # 95 % quantile of chi^2 with 1 degree of freedom
SCAN_FIRST_STEP = 1.0 / 40.0
SCAN_REFINEMENTS = 16  # samples that shrink a bracketed crossing, at most (every other one halves it)
SCAN_RESOLUTION = 0.005  # a bracket this share of the parameter's range is fine enough
SCAN_TOLERANCE = 0.05  # a sample whose excess is within 5 % of the threshold is the crossing
FLAT_SHARE = 0.05  # a profile is flat where its cost is within 5 % of the 95 % region's rise of the fit
JACOBIAN_STEP = 0.01
POLISH_ITERATIONS = 3
BOOTSTRAP_SAMPLES = 1000
BOOTSTRAP_SEED = 0
IDENTIFIED_SHARE = 1e-3  # a resample keeping less of the trials' smallest scaled singular value leaves one undetermined


def residual_jacobian(model: FittedCauses, nominal, setting, trials) -> tuple[np.ndarray, np.ndarray]:
    """The residual vector at the fit and its Jacobian in u, by central differences of
    ``JACOBIAN_STEP`` of each parameter's range (one-sided at a bound)."""
    u0 = model.vector()
    lo, hi = model.bounds()

    def r(u):
        return residuals(replay_all(setting, model.with_vector(u).plant(nominal), trials), trials)

    r0 = r(u0)
    J = np.empty((len(r0), len(u0)))
    for j in range(len(u0)):
        h = JACOBIAN_STEP * (hi[j] - lo[j])
        up, down = u0.copy(), u0.copy()
        up[j], down[j] = min(u0[j] + h, hi[j]), max(u0[j] - h, lo[j])
        J[:, j] = (r(up) - r(down)) / (up[j] - down[j])
    return r0, J


def gauss_newton_polish(model: FittedCauses, nominal, setting, trials):
    """Up to ``POLISH_ITERATIONS`` Gauss-Newton steps from the derivative-free fit (each full,
    else half, kept only when it lowers the cost); returns the model, its residuals and their
    Jacobian (for the profile directions and the bootstrap)."""
    lo, hi = model.bounds()
    r0, J = residual_jacobian(model, nominal, setting, trials)
    for _ in range(POLISH_ITERATIONS):
        step = np.linalg.lstsq(J, -r0, rcond=None)[0]
        for fraction in (1.0, 0.5):
            u = np.clip(model.vector() + fraction * step, lo, hi)
            if cost_of(model.with_vector(u).plant(nominal), setting, trials) < float(r0 @ r0):
                model = model.with_vector(u)
                r0, J = residual_jacobian(model, nominal, setting, trials)
                break
        else:
            break
    return model, r0, J


def bootstrap_intervals(model: FittedCauses, r: np.ndarray, J: np.ndarray, sizes: list[int]) -> np.ndarray:
    """95 % intervals in u from a one-step bootstrap over trials: ``BOOTSTRAP_SAMPLES``
    resamples of the trials (with replacement), each refitted by the Gauss-Newton step from
    the fit, u_b = u* - pinv(J_b) r_b, with the residual blocks and Jacobian rows of the drawn
    trials. Returns (parameters, 2): the union of the percentile interval and
    u* +- t_0.975(n - p) sqrt(n / (n - 1)) sd(u_b), n trials and p parameters: with a dozen
    trials the bootstrap spread underestimates the sampling spread, and the Student quantile
    and the n / (n - 1) factor are the small-sample corrections of a trial-clustered standard
    error.

    A resample that does not determine the parameters is left out: the smallest singular value
    of its Jacobian rows, each column scaled by its norm over all trials
    (``smallest_scaled_singular_value``), below ``IDENTIFIED_SHARE`` of all trials' (a resample
    of as many trials has about theirs). One that drew only trials insensitive to a parameter
    (friction from impacts without a tangential speed: the Jacobian's column there is
    finite-difference rounding, 1e-11) has no estimate of it, and its Gauss-Newton step (1e10)
    would land on a bound of the fit and widen the interval across the nominal value."""
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    edges = np.concatenate([[0], np.cumsum(sizes)])
    blocks = [np.arange(a, b) for a, b in zip(edges[:-1], edges[1:])]
    lo, hi = model.bounds()
    u0 = model.vector()
    samples = np.empty((BOOTSTRAP_SAMPLES, len(u0)))
    kept = np.empty(BOOTSTRAP_SAMPLES, bool)
    scale = np.where(np.linalg.norm(J, axis=0) > 0.0, np.linalg.norm(J, axis=0), 1.0)
    floor = IDENTIFIED_SHARE * smallest_scaled_singular_value(J, scale)
    for b in range(BOOTSTRAP_SAMPLES):
        rows = np.concatenate([blocks[i] for i in rng.integers(0, len(blocks), len(blocks))])
        kept[b] = smallest_scaled_singular_value(J[rows], scale) >= floor
        samples[b] = np.clip(u0 - np.linalg.lstsq(J[rows], r[rows], rcond=None)[0], lo, hi)
    samples = samples[kept] if kept.any() else u0[None, :]
    n = len(blocks)
    half = student_t.ppf(0.975, max(n - len(u0), 1)) * np.sqrt(n / max(n - 1, 1)) * samples.std(axis=0)
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return np.stack([np.maximum(np.minimum(low, u0 - half), lo), np.minimum(np.maximum(high, u0 + half), hi)], axis=1)


def smallest_scaled_singular_value(J: np.ndarray, scale: np.ndarray) -> float:
    """The smallest singular value of ``J`` with each column divided by ``scale`` (its norm over
    all residuals): how well the rows of ``J`` determine the least determined combination of
    the parameters, in units of each parameter's whole sensitivity."""
    return float(np.linalg.svd(J / scale, compute_uv=False)[-1])


def profile_direction(J: np.ndarray, index: int) -> np.ndarray:
    """Direction in u along which parameter ``index`` moves by 1 while the others follow the
    linearised profile: d_o = -pinv(J_o) J_i, the least-squares re-fit of the others."""
    others = [j for j in range(J.shape[1]) if j != index]
    d = np.zeros(J.shape[1])
    d[index] = 1.0
    if others:
        d[others] = -np.linalg.lstsq(J[:, others], J[:, index], rcond=None)[0]
    return d


@dataclass(frozen=True)
class ProfileRegion:
    """The polished fit and its 95 % region, shared by the profile scans: the fitted ``model``
    on top of ``nominal``, its cost ``cost0`` over ``trials``, and the rise of the cost above
    ``cost0`` (``threshold``) that leaves the region."""

    model: FittedCauses
    nominal: PlantParameters
    setting: ReplaySetting
    trials: tuple[MeasuredTrial, ...]
    cost0: float
    threshold: float


@dataclass(frozen=True)
class ScanTask:
    """One side (``sign``) of the profile scan of entry ``index`` of the fitted vector along
    ``direction`` (``profile_direction``): one process task."""

    region: ProfileRegion
    index: int
    sign: float
    direction: np.ndarray


def crossing_u(task: ScanTask) -> float | None:
    """Where the cost's excess over the fitted cost reaches the region's threshold along one
    parameter's profile path, on one side (one process task): ``profile_crossing``, the
    others following their linearised profile (``direction``, clipped to their bounds). The
    parameter's u there, or None when it reaches its bound first."""
    region, index = task.region, task.index
    model, trials = region.model, list(region.trials)
    u0 = model.vector()
    lo, hi = model.bounds()

    def excess(x):
        u = np.clip(u0 + (x - u0[index]) * task.direction, lo, hi)
        return cost_of(model.with_vector(u).plant(region.nominal), region.setting, trials) - region.cost0

    limit = hi[index] if task.sign > 0 else lo[index]
    return profile_crossing(excess, u0[index], limit, hi[index] - lo[index], region.threshold)


def scan_side(task: ScanTask) -> float | None:
    """Where the cost leaves the 95 % region along one parameter's profile path, on one side
    (one process task, ``crossing_u``): the theta of the crossing, or None when the parameter
    reaches its bound inside the region (open side)."""
    x = crossing_u(task)
    if x is None:
        return None
    model, index = task.region.model, task.index
    cause_index, local = parameter_owner(model, index)
    u = model.u[cause_index].copy()
    u[local] = x
    return float(model.causes[cause_index].to_theta(u)[local])


def profile_crossing(excess, start: float, limit: float, span: float, threshold: float) -> float | None:
    """Where ``excess`` (the cost's rise above the fit along a profile, 0 at ``start``) first
    reaches ``threshold`` between ``start`` and ``limit`` (the fit's bound), or None when it
    stays below it there (an open side). ``span``: the parameter's range.

    Steps that double (``SCAN_FIRST_STEP`` of the span first) bracket the crossing; the bracket
    then shrinks until the excess at the interpolated point is within ``SCAN_TOLERANCE`` of the
    threshold or the bracket within ``SCAN_RESOLUTION`` of the span (at most
    ``SCAN_REFINEMENTS`` samples): the samples are in turn the straight line's crossing between
    the bracket's ends (the midpoint when that falls in the bracket's outer tenths) and the
    midpoint, so the bracket halves at least every other sample, and where the cost changes
    slope (a friction profile flat down to the stick/slip kink and steep below it: a line drawn
    across the kink puts the crossing at the flat end, a bound that excludes the truth) the
    samples close in on the kink. The answer is the line's crossing in the last bracket: on a
    smooth profile one or two samples confirm it, densely sampled only where the slope
    changes."""
    sign = 1.0 if limit >= start else -1.0
    inside, inside_excess = start, 0.0
    step = SCAN_FIRST_STEP * span
    while True:
        x = start + sign * step
        x = min(x, limit) if sign > 0 else max(x, limit)
        value = excess(x)
        if value >= threshold:
            outside, outside_excess = x, value
            break
        if x == limit:
            return None
        inside, inside_excess = x, max(value, 0.0)
        step *= 2.0
    for k in range(SCAN_REFINEMENTS):
        fraction = (threshold - inside_excess) / max(outside_excess - inside_excess, 1e-12)
        if abs(outside - inside) <= SCAN_RESOLUTION * span:
            break
        line = k % 2 == 0 and 0.1 <= fraction <= 0.9
        middle = inside + (fraction if line else 0.5) * (outside - inside)
        value = excess(middle)
        if abs(value - threshold) <= SCAN_TOLERANCE * threshold:
            return float(middle)
        if value >= threshold:
            outside, outside_excess = middle, value
        else:
            inside, inside_excess = middle, max(value, 0.0)
    fraction = (threshold - inside_excess) / max(outside_excess - inside_excess, 1e-12)
    return float(inside + fraction * (outside - inside))


def at_flat_ends(region: ProfileRegion, tasks: list[ScanTask], ends: list, jobs: int) -> FittedCauses:
    """The fit with every parameter open on one side only (``ends``: the profile scans'
    crossings of ``tasks``, None for an open side) moved along its profile path to the near end
    of the profile's flat part: where, towards the closed side, the cost first rises
    ``FLAT_SHARE`` of the region's threshold above the fit. On a flat profile (friction where
    every impact sticks: mu = 1.0 fits as well as 0.4) the fit stops anywhere on the flat part,
    a value the data do not single out; the near end of the flat part is the one they do
    (the smallest mu with which every impact sticks). The others follow the parameter's
    profile path; the intervals are unchanged (the moved value lies inside them)."""
    flat = replace(region, threshold=FLAT_SHARE * region.threshold)
    moves = [replace(tasks[2 * i + (ends[2 * i] is None)], region=flat) for i in range(len(tasks) // 2)
             if (ends[2 * i] is None) != (ends[2 * i + 1] is None)]
    if not moves:
        return region.model
    u0 = region.model.vector()
    u = u0.copy()
    for task, x in zip(moves, map_in_processes(crossing_u, moves, jobs)):
        if x is not None:
            u += (x - u0[task.index]) * task.direction
    return region.model.with_vector(np.clip(u, *region.model.bounds()))


def parameter_owner(model: FittedCauses, index: int) -> tuple[int, int]:
    """(cause index, parameter index within the cause) of entry ``index`` of the vector."""
    for k, u in enumerate(model.u):
        if index < len(u):
            return k, index
        index -= len(u)
    raise IndexError(index)


def parameter_labels(model: FittedCauses) -> list[str]:
    """The label of every fitted parameter of ``model``, in the order of its vector."""
    return [label for cause in model.causes for label in cause.labels]


def parameter_intervals(model: FittedCauses, nominal, setting, trials, jobs: int) -> tuple[FittedCauses, list[list]]:
    """The fit polished by Gauss-Newton, and 95 % intervals of every fitted parameter theta
    (per cause, per parameter, [low, high], None for an open side).

    Each interval is the union of two: the profile-likelihood interval (``scan_side``: with
    Gaussian residuals of unknown common scale s, the region cost - cost_min <= CHI2_95 s^2,
    s^2 = cost_min / (residuals - parameters)) and the percentile interval of a one-step
    bootstrap over trials (``bootstrap_intervals``), which also carries the trial-to-trial
    errors that the residual scale misses (e.g. of the replay's start state). A side is open
    when the profile scan reaches the bound of the fit still inside the region: the data do
    not bound the parameter there (``docs/diagnosis.md``)."""
    if not model.causes:
        return model, []
    model, r, J = gauss_newton_polish(model, nominal, setting, trials)
    cost0 = float(r @ r)
    threshold = CHI2_95 * cost0 / max(len(r) - len(model.vector()), 1)
    region = ProfileRegion(model, nominal, setting, tuple(trials), cost0, threshold)
    tasks = [
        ScanTask(region, i, sign, profile_direction(J, i))
        for i in range(len(model.vector()))
        for sign in (-1.0, 1.0)
    ]
    names = parameter_labels(model)
    labels = [f"{names[task.index]} {'low' if task.sign < 0 else 'high'} side" for task in tasks]

    def done(k: int, total: int) -> None:
        log.info("diagnose: profile %d/%d %s", k, total, labels[k - 1])

    ends = map_in_processes(scan_side, tasks, jobs, done)
    boot = bootstrap_intervals(model, r, J, residual_sizes(trials))
    model = at_flat_ends(region, tasks, ends, jobs)
    out, k = [], 0
    for cause, u in zip(model.causes, model.u):
        intervals = []
        for j in range(len(u)):
            low, high = ends[k + 2 * j], ends[k + 2 * j + 1]
            at = u.copy()
            at[j] = boot[k // 2 + j, 0]
            boot_low = float(cause.to_theta(at)[j])
            at[j] = boot[k // 2 + j, 1]
            boot_high = float(cause.to_theta(at)[j])
            # a bootstrap end at the fit's bound is degenerate: it does not widen the profile
            bound_lo, bound_hi = cause.u_bounds()
            degenerate = boot[k // 2 + j, 0] <= bound_lo[j] or boot[k // 2 + j, 1] >= bound_hi[j]
            intervals.append([
                None if low is None else (low if degenerate else min(low, boot_low)),
                None if high is None else (high if degenerate else max(high, boot_high)),
            ])
        out.append(intervals)
        k += 2 * len(u)
    return model, out


def holds(value: float, interval) -> bool:
    """Whether ``value`` lies in ``interval`` ([low, high], None for an open side)."""
    low, high = interval
    return (low is None or low <= value) and (high is None or value <= high)


def without_spurious(model: FittedCauses, theta_intervals: list[list], nominal, setting, trials,
                     jobs: int) -> tuple[FittedCauses, list[list]]:
    """``model`` and its intervals (``parameter_intervals``) with every spurious parameter
    dropped: in a cause of separate effects (``Cause.separable``: one per joint or joint group)
    that moves the plant on evidence (a parameter's interval excludes its nominal value), each
    parameter whose interval holds its nominal value is held there
    (``causes.FixedParameters``), the others refitted and bounded again. The returned model has
    the full causes (a dropped parameter at its nominal value) and a dropped parameter keeps
    the interval that held its nominal value: what the data say of it (e.g. a damping of at
    most its upper end). A cause none of whose intervals excludes its nominal value stays as
    it is: it explains nothing (``excludes_nominal``)."""
    held = []
    for cause, intervals in zip(model.causes, theta_intervals):
        values = cause.nominal_theta(nominal)
        inside = [holds(v, interval) for v, interval in zip(values, intervals)]
        spurious = cause.separable and not all(inside)
        held.append({j: float(values[j]) for j, h in enumerate(inside) if h} if spurious else {})
    if not any(held):
        return model, theta_intervals
    reduced = FittedCauses(
        tuple(FixedParameters(c, h) if h else c for c, h in zip(model.causes, held)),
        tuple(u[[j for j in range(len(u)) if j not in h]] for u, h in zip(model.u, held)),
    )
    reduced, reduced_intervals = parameter_intervals(reduced, nominal, setting, trials, jobs)
    causes, u_all, out = [], [], []
    for cause, before, fitted, u, intervals, h in zip(reduced.causes, theta_intervals, model.causes, reduced.u,
                                                       reduced_intervals, held):
        if h:
            free = iter(intervals)
            intervals = [before[j] if j in h else next(free) for j in range(len(before))]
            cause, u = fitted, fitted.to_u(cause.full_theta(cause.to_theta(u)))
        causes.append(cause)
        u_all.append(u)
        out.append(intervals)
    return FittedCauses(tuple(causes), tuple(u_all)), out


def excludes_nominal(model: FittedCauses, theta_intervals: list[list], nominal: PlantParameters) -> list[bool]:
    """Per cause of ``model``: whether the interval of at least one of its parameters excludes
    the parameter's nominal value (the cause moves the plant away from the nominal on evidence)."""
    found = []
    for cause, intervals in zip(model.causes, theta_intervals):
        values = cause.nominal_theta(nominal)
        found.append(any(not holds(v, interval) for v, interval in zip(values, intervals)))
    return found


def override_intervals(model: FittedCauses, theta_intervals: list[list]) -> dict:
    """Intervals of the plant override keys: for each key, [low, high] (a list of them for a
    vector); each entry takes the interval of the fitted parameter that moves it (an entry no
    parameter moves gets [value, value]); None for an open side."""
    result: dict = {}
    for cause, u, intervals in zip(model.causes, model.u, theta_intervals):
        theta = cause.to_theta(u)
        base = cause.overrides(theta)
        entries = {k: [[v, v] for v in np.atleast_1d(value).tolist()] for k, value in base.items()}
        for j, (low, high) in enumerate(intervals):
            moved = theta.copy()
            moved[j] = theta[j] + max(1e-3 * abs(theta[j]), 1e-6)
            changed = cause.overrides(moved)
            for key, value in changed.items():
                for e, (old, new) in enumerate(zip(np.atleast_1d(base[key]), np.atleast_1d(value))):
                    if old != new:
                        ends = []
                        for end in (low, high):
                            if end is None:
                                ends.append(None)
                            else:
                                at = theta.copy()
                                at[j] = end
                                ends.append(float(np.atleast_1d(cause.overrides(at)[key])[e]))
                        entries[key][e] = ends
        for key, value in base.items():
            result[key] = entries[key] if isinstance(value, list) else entries[key][0]
    return result


def open_sides(model: FittedCauses, theta_intervals: list[list], trials: list[MeasuredTrial],
               nominal: PlantParameters) -> list[dict]:
    """Every parameter the data leave open on a side, with the trials that would settle it
    (in terms of the normal speeds of ``trials``). A side open down to the parameter's floor
    when the nominal value is at or below that floor (no effect: an armature or a damping of 0,
    whose fit's floor is 0 or, on a log scale, the smallest effect it models) is
    ``negligible``: the data say the effect is at most the interval's other end, and more
    trials would not change that."""
    normal_speeds = np.array([t.reference_speed for t in trials])
    found = []
    for cause, u, intervals in zip(model.causes, model.u, theta_intervals):
        floor = cause.to_theta(cause.u_bounds()[0])
        at_nominal = floor >= cause.nominal_theta(nominal) - 1e-12
        for j, (low, high) in enumerate(intervals):
            for side, end, other in (("below", low, high), ("above", high, low)):
                # what the data do tell: the closed end of the interval, else the fitted value
                known = float(cause.to_theta(u)[j]) if other is None else float(other)
                if end is None:
                    negligible = side == "below" and bool(at_nominal[j])
                    found.append(
                        {
                            "cause": cause.name,
                            "parameter": cause.labels[j],
                            "side": side,
                            "fitted": float(cause.to_theta(u)[j]),
                            "negligible": negligible,
                            "trials_needed": "" if negligible else cause.settling_trials(j, side, known, normal_speeds),
                        }
                    )
    return found


def open_side_text(side: dict, interval) -> str:
    """One open side (``open_sides``) in words: a negligible parameter and its upper end, or
    the trials that would settle it."""
    if side["negligible"]:
        high = interval[1]
        bound = "at most its upper bound" if high is None else f"at most {high:.4g}"
        return f"{side['parameter']} is negligible ({bound}: the data are consistent with none)."
    return f"The data cannot bound {side['parameter']} {side['side']}: {side['trials_needed']}."
