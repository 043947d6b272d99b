"""What the nominal simulation and the predictors get wrong on the measured trials.

**Compare** (``error_analysis``): errors (25) and average errors (26) of the nominal simulation
per joint, posture and speed; their sign (the least-squares ratio of simulated to measured jump
per joint, > 1: the simulation overshoots) and their scaling with speed (slope of (26) against
the reference speed); the share of the error carried by each joint. The classical, GM and CRB
predictions are evaluated at the logged pre-impact states (v- = J dq-, c_r = 0)
(``predictor_errors``).
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.jump import JUMP_MODELS, METHODS
from impactqp.controller.model.jump_error import average_prediction_error

from .trials import MeasuredTrial, ReplaySetting


def predictor_errors(trials: list[MeasuredTrial], setting: ReplaySetting) -> tuple[dict, dict, dict]:
    """Average error (26) of each predictor at the logged pre-impact states (v- = J dq-,
    c_r = 0): with its own impulse, and fed the measured impulse where a force log exists.
    Also returns the predicted jumps (trials x joints) per method."""
    robot = setting.choice.model()
    own = {m: [] for m in METHODS}
    fed = {m: [] for m in METHODS}
    predictions = {m: [] for m in METHODS}
    for trial in trials:
        terms = robot.terms(trial.q_pre, trial.dq_pre, check_limits=False)
        v_minus = terms.J @ trial.dq_pre
        for m in METHODS:
            jump = JUMP_MODELS[m].predict(terms, setting.surface.normal, v_minus, 0.0).dq_jump
            predictions[m].append(jump)
            own[m].append(average_prediction_error(jump, trial.jump))
            if trial.impulse is not None:
                measured = JUMP_MODELS[m].predict(terms, setting.surface.normal, v_minus, 0.0, impulse=trial.impulse)
                fed[m].append(average_prediction_error(measured.dq_jump, trial.jump))
    return (
        {m: float(np.mean(own[m])) for m in METHODS},
        {m: float(np.mean(fed[m])) for m in METHODS if fed[m]},
        {m: np.array(p) for m, p in predictions.items()},
    )


def error_analysis(trials: list[MeasuredTrial], nominal_jumps: np.ndarray) -> dict:
    """The comparison of the nominal replays' detected jumps ``nominal_jumps`` with the measured
    ones (module docstring), for the report."""
    measured = np.array([t.jump for t in trials])
    errors = nominal_jumps - measured  # eq. (25)
    speeds = np.array([t.reference_speed for t in trials])
    avg = np.mean(np.abs(errors), axis=1)  # eq. (26)
    ratio = np.sum(nominal_jumps * measured, axis=0) / np.maximum(np.sum(measured**2, axis=0), 1e-12)
    share = np.sum(np.abs(errors), axis=0) / max(np.sum(np.abs(errors)), 1e-12)
    slope = float(np.polyfit(speeds, avg, 1)[0]) if np.ptp(speeds) > 0 else 0.0
    groups: dict[str, dict[str, list[float]]] = {}
    for t, e in zip(trials, avg):
        key = f"{t.reference_speed:.3f}" + (f"+t{t.tangential_speed:.3f}" if t.tangential_speed else "")
        groups.setdefault(t.posture or "unknown", {}).setdefault(key, []).append(float(e))
    return {
        "per_joint_mean_error": np.mean(errors, axis=0).tolist(),
        "per_joint_mean_abs_error": np.mean(np.abs(errors), axis=0).tolist(),
        "per_joint_sim_to_measured_ratio": ratio.tolist(),
        "per_joint_error_share": share.tolist(),
        "error_vs_speed_slope": slope,
        "per_posture_speed": {p: {k: float(np.mean(v)) for k, v in d.items()} for p, d in groups.items()},
    }
