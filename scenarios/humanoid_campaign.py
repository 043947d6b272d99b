"""The humanoid campaign: stances x hand speeds of ``sim.humanoid_trial``, and its table.

For each trial and predictor (classical, gm, crb, each fed its own impulse; ``momentum``: the
feet-held momentum law fed the measured impulse) the average error (26) over the joints; the
table gives per stance and speed the measured contact speed, the impulse, the CoM velocity jump,
the foot slip and lift, whether the robot fell, and the errors; its last row averages the errors
over every trial, with the reduction 100 (1 - e_crb / e_classical) % of CRB against classical
(negative when CRB is worse).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel
from impactqp.sim.humanoid_trial import SCRIPTED, SERVO_GAIN, ImpactTrial, run_impact_trial

DEFAULT_SPEEDS = (0.1, 0.2, 0.3, 0.4)
PREDICTORS = (*METHODS, "momentum")


def run_campaign(
    robot: FloatingBaseModel,
    stances: Iterable[str] | None = None,
    speeds: Iterable[float] = DEFAULT_SPEEDS,
    gain: float = SERVO_GAIN,
    armature=None,
    source=SCRIPTED,
) -> list[ImpactTrial]:
    """One trial per stance (None: every stance of the robot's description) and commanded hand
    speed (m/s); ``gain`` is the servo bandwidth (rad/s), ``armature`` the plant's rotor inertia
    (kg m^2): None for the G1's actuators (``controller.model.g1_actuators``), one number for every
    joint (0: link-only) or one per joint; ``source`` the command source
    (``sim.humanoid_trial.SCRIPTED`` or ``sim.humanoid_qp_source.QpCommand``)."""
    all_stances = robot.description.stances
    return [
        run_impact_trial(robot, all_stances[name], speed, gain=gain, armature=armature, source=source)
        for name in (all_stances if stances is None else stances)
        for speed in speeds
    ]


def mean_errors(trials: list[ImpactTrial]) -> dict[str, float]:
    """Eq. (26) averaged over the trials, per predictor."""
    return {m: float(np.mean([t.errors[m] for t in trials])) for m in PREDICTORS}


def crb_reduction(errors: dict[str, float]) -> float:
    """100 (1 - e_crb / e_classical) %: how much CRB cuts the classical error (negative: worse)."""
    return 100.0 * (1.0 - errors["crb"] / errors["classical"])


def campaign_table(trials: list[ImpactTrial]) -> str:
    """The campaign as a Markdown table (module docstring)."""
    head = ("| stance | v cmd (m/s) | v contact (m/s) | impulse n (N s) | CoM jump x (m/s) | slip (mm) | "
            "lift (mm) | fell | " + " | ".join(f"e {m}" for m in PREDICTORS) + " |")
    lines = [head, "|" + "---|" * (8 + len(PREDICTORS))]
    for t in trials:
        lines.append(
            f"| {t.stance} | {t.speed:.2f} | {t.contact_speed:.3f} | {-t.impulse[0]:.3f} | "
            f"{t.measured_com_jump[0]:.4f} | {1e3 * t.foot_slip:.2f} | {1e3 * t.foot_lift:.2f} | "
            f"{'yes' if t.fell else 'no'} | " + " | ".join(f"{t.errors[m]:.4f}" for m in PREDICTORS) + " |"
        )
    errors = mean_errors(trials)
    lines.append(
        f"| **mean** ({len(trials)} trials) | | | | | | | | " + " | ".join(f"**{errors[m]:.4f}**" for m in PREDICTORS)
        + " |"
    )
    lines.append("")
    lines.append(f"CRB against classical: {crb_reduction(errors):+.1f} % (positive: CRB is better).")
    return "\n".join(lines)
