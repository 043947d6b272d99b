"""Impact detection and jump extraction (paper Sec. V-A), for simulated and measured logs alike.

:func:`measure_impact` reads one trial log (:class:`controller.measured.trial_log.TrialLog`: control-rate t, q, dq,
tau, dq_cmd and, when present, a contact-force log) and applies these rules:

Detection
    With a force log: contact starts at the first force sample with |f| > ``force_threshold``
    (t_c), and the impact is detected at the first control sample at or after it (t_d).
    Without one: by the joint-torque residual, as on the robot [5, Sec. VI]. The residual of a
    joint is r_k = tau_k - tau^_k, with tau^_k the value at t_k of the least-squares line through
    the ``TREND_SAMPLES`` previous torques (a causal FIR filter: the expected torque trend); the
    impact is detected at the first sample where |r_k| > max(``torque_threshold``,
    6 sigma_j) for some joint j, sigma_j = 1.4826 median_k |r_jk| (robust noise level).
    Contact start is then the last sample before t_d whose residuals all stayed below half of
    that threshold.

Pre-impact state
    k- = the last control sample at or before t_c; q- = q[k-],
    dq- = mean(dq[k- - 2 .. k-]) (3 samples: noise std / sqrt 3 at constant approach velocity).

Jump
    Searched, as in the paper, in the window [t_d - 5 ms, t_d + 20 ms]: k+ is the sample after
    k- in the window where the joint-velocity change ||dq_k - dq-||_2 is largest (one time for
    all joints: the end of the contact phase, before the servo pulls the joints back), and
    dq_jump = mean(dq[k+ - 1 .. k+ + 1]) - dq- (3 samples against encoder noise; the velocity is
    flat around its extremum). With a rigid contact and no servo this is the rigid-body jump of
    the whole impact (compression and restitution).

Impulse and duration (force log only)
    The first contact phase runs from t_c to the first later force sample with |f| <= the
    threshold (t_e, or the end of the log); duration = t_e - t_c and impulse = the trapezoidal
    integral of f over [sample before t_c, t_e]. (For MuJoCo's piecewise-constant force samples
    the exact impulse is sum f_i h; the trapezoid differs from it by half of the two end samples,
    both below the threshold: 1e-4 relative here.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.validation import BadInputError

from .trial_log import TrialLog

WINDOW_BEFORE = 5e-3
WINDOW_AFTER = 20e-3
PRE_SAMPLES = 3
POST_HALF_WIDTH = 1
TREND_SAMPLES = 10
DEFAULT_FORCE_THRESHOLD = 1.0
DEFAULT_TORQUE_THRESHOLD = 0.3
NOISE_SIGMAS = 6.0


class ImpactNotFoundError(BadInputError):
    """The log holds no detectable impact, or too little data around it."""


@dataclass(frozen=True)
class ImpactMeasurement:
    """The impact of one trial.

    ``method`` is "force" or "torque_residual". Indices refer to the control-rate samples of the
    log. ``impulse`` (N s, world frame, on the robot) and ``duration`` (s) are None without a
    force log. ``window`` is the (first, last) sample index of the search window. A log without
    a detectable impact raises :class:`ImpactNotFoundError` instead of returning a measurement.
    """

    method: str
    t_detect: float
    t_contact_start: float
    detect_index: int
    pre_index: int
    post_index: int
    window: tuple[int, int]
    q_pre: np.ndarray
    dq_pre: np.ndarray
    dq_post: np.ndarray
    dq_jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None


def trend_filter(samples: int) -> np.ndarray:
    """Weights w_1..w_m of the one-step least-squares linear extrapolation tau^_k = sum w_j
    tau_{k-j}: the value at lag 0 of the line fitted to the m previous samples."""
    lags = np.arange(1, samples + 1, dtype=float)
    design = np.column_stack([np.ones(samples), -lags])
    return np.linalg.solve(design.T @ design, design.T)[0]


def torque_residual(tau: np.ndarray, samples: int = TREND_SAMPLES) -> np.ndarray:
    """r_k = tau_k - tau^_k for k >= samples (rows before are NaN): (N, joints)."""
    weights = trend_filter(samples)
    residual = np.full_like(tau, np.nan)
    prediction = sum(w * tau[samples - j : len(tau) - j] for j, w in enumerate(weights, start=1))
    residual[samples:] = tau[samples:] - prediction
    return residual


def measure_impact(
    log: TrialLog,
    *,
    force_threshold: float = DEFAULT_FORCE_THRESHOLD,
    torque_threshold: float = DEFAULT_TORQUE_THRESHOLD,
    use_force: bool = True,
) -> ImpactMeasurement:
    """Detect the impact of ``log`` and measure its jump (rules in the module docstring).

    ``use_force=False`` ignores the force log for detection (the robot's own torque residual),
    the impulse is still integrated when a force log exists. Raises
    :class:`ImpactNotFoundError` when nothing is detected or the window does not fit the log.
    """
    t, dq = log.t, log.dq
    n = len(t)
    if n < TREND_SAMPLES + 2:
        raise ImpactNotFoundError(f"the log has only {n} samples")
    period = float(np.median(np.diff(t)))
    contact = _force_contact(log, force_threshold) if log.has_force else None

    if contact is not None and use_force:
        method = "force"
        t_contact_start = contact[0]
        detect_index = int(np.searchsorted(t, t_contact_start - 1e-9 * period))
        if detect_index >= n:
            raise ImpactNotFoundError("the contact starts after the last control sample")
        pre_index = int(np.searchsorted(t, t_contact_start + 1e-9 * period, side="right")) - 1
    else:
        method = "torque_residual"
        detect_index, pre_index = _torque_detection(log.tau, torque_threshold)
        t_contact_start = float(t[pre_index])

    first = detect_index - int(round(WINDOW_BEFORE / period))
    last = detect_index + int(round(WINDOW_AFTER / period))
    if pre_index - (PRE_SAMPLES - 1) < 0 or first < 0:
        raise ImpactNotFoundError(
            f"the impact at t = {t[detect_index]:.4f} s is less than {WINDOW_BEFORE * 1e3:.0f} ms "
            "after the start of the log"
        )
    if last + POST_HALF_WIDTH >= n:
        raise ImpactNotFoundError(
            f"the log ends less than {WINDOW_AFTER * 1e3:.0f} ms after the impact detected at "
            f"t = {t[detect_index]:.4f} s"
        )
    dq_pre = dq[pre_index - PRE_SAMPLES + 1 : pre_index + 1].mean(axis=0)
    candidates = np.arange(max(pre_index + 1, first), last + 1)
    change = np.linalg.norm(dq[candidates] - dq_pre, axis=1)
    post_index = int(candidates[np.argmax(change)])
    dq_post = dq[post_index - POST_HALF_WIDTH : post_index + POST_HALF_WIDTH + 1].mean(axis=0)

    impulse = duration = None
    if contact is not None:
        _, _, impulse, duration = contact
    return ImpactMeasurement(
        method=method,
        t_detect=float(t[detect_index]),
        t_contact_start=float(t_contact_start),
        detect_index=detect_index,
        pre_index=pre_index,
        post_index=post_index,
        window=(first, last),
        q_pre=log.q[pre_index].copy(),
        dq_pre=dq_pre,
        dq_post=dq_post,
        dq_jump=dq_post - dq_pre,
        impulse=impulse,
        duration=duration,
    )


def _force_contact(log: TrialLog, threshold: float):
    """(t_c, t_e, impulse, duration) of the first contact phase, or None without contact."""
    magnitude = np.linalg.norm(log.force, axis=1)
    above = magnitude > threshold
    if not above.any():
        return None
    start = int(np.argmax(above))
    below_after = np.flatnonzero(~above[start:])
    end = start + int(below_after[0]) if below_after.size else len(above) - 1
    lo = max(start - 1, 0)
    ft, f = log.force_t[lo : end + 1], log.force[lo : end + 1]
    impulse = 0.5 * ((f[1:] + f[:-1]) * np.diff(ft)[:, None]).sum(axis=0)
    t_c, t_e = float(log.force_t[start]), float(log.force_t[end])
    return t_c, t_e, impulse, t_e - t_c


def _torque_detection(tau: np.ndarray, floor: float) -> tuple[int, int]:
    """(detection index, contact-start index) from the torque residual."""
    residual = torque_residual(tau)
    valid = residual[TREND_SAMPLES:]
    sigma = 1.4826 * np.median(np.abs(valid), axis=0)
    threshold = np.maximum(floor, NOISE_SIGMAS * sigma)
    exceed = np.any(np.abs(valid) > threshold, axis=1)
    if not exceed.any():
        raise ImpactNotFoundError(
            f"no joint-torque residual exceeds its threshold (max residual/threshold "
            f"{np.max(np.abs(valid) / threshold):.2f})"
        )
    detect = TREND_SAMPLES + int(np.argmax(exceed))
    start = detect
    while start > TREND_SAMPLES and np.any(np.abs(residual[start - 1]) > 0.5 * threshold):
        start -= 1
    return detect, start - 1
