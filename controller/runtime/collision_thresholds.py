"""The collision-reflex thresholds a robot run sets (libfranka's ``set_collision_behavior``): by
default from the predicted impact of the run (``[libfranka] collision_thresholds =
"from_impact"``), else the ``[libfranka]`` table's lists (``"fixed"``).

**Predicted peaks.** At the start posture q, approached along -n at the asked contact speed v
(d = J6+ [-n; 0] v, ``max_speed.unit_impact``), each jump predictor of the configuration's
``[impact] jump_model`` gives the contact impulse iota = v iota_1, linear in v (eqs. (6) and
(12): iota = G J d). Spread over the impact duration delta_t (``[impact] impact_duration``, the
one the impulsive-torque constraint and the closed-form max speed use), the peaks are

  joint torques   tau_i = |J^T iota|_i / delta_t               (the impulsive joint torque)
  Cartesian       f_k = |iota_k| / delta_t,  m_k = |(r x iota)_k| / delta_t

(world axes; r the contact point from the flange, whose moment the robot's Cartesian estimate
holds when its stiffness frame lies between the flange and the contact point), the largest over
the predictors ("robust": crb, gm and classical).

**Thresholds.** Each entry is k peak (k = ``impact_threshold_factor``), never below the
``[libfranka]`` defaults (``DEFAULT_TORQUE_THRESHOLDS``, ``DEFAULT_FORCE_THRESHOLDS``) and at
most the largest the table accepts (``MAX_COLLISION_TORQUE``, ``MAX_COLLISION_FORCE``):
min(max, max(default, k peak)); lower = upper (a contact between the two would only be flagged).
A list the table gives wins over the computed one (an upper list below a given lower one is
raised to it). The peaks, hence the thresholds between their bounds, are linear in v.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.constraints.impact_model import jump_model_names
from impactqp.controller.config.controller_config import ImpactConfig
from impactqp.controller.model.max_speed import Setting, unit_impact
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.robot_config import (
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    FROM_IMPACT,
    MAX_COLLISION_FORCE,
    MAX_COLLISION_TORQUE,
    RobotConfig,
)


@dataclass(frozen=True)
class ImpactPeaks:
    """The predicted peaks of an impact (module docstring): ``speed`` v (m/s), ``duration``
    delta_t (s), the impulse ``impulse`` iota (N s, world; the predictors' largest), ``torque``
    tau (N m per joint) and ``wrench`` (f, m: N and N m, world axes)."""

    speed: float
    duration: float
    impulse: np.ndarray
    torque: np.ndarray
    wrench: np.ndarray


def predicted_peaks(model: PandaModel, q, normal, speed: float, impact: ImpactConfig) -> ImpactPeaks:
    """The peaks of the impact at ``q`` against the surface ``normal`` at ``speed`` (module
    docstring), with the predictors, restitution and duration of ``impact``."""
    q = np.asarray(q, dtype=float)
    terms = model.terms(q, np.zeros(model.nv))
    contact = model.contact_frame(q).translation  # forward kinematics of q: the flange's placement below
    flange = model.data.oMf[model.model.getFrameId(model.description.flange_frame)].translation
    impulses = [
        speed * unit_impact(model, terms, normal, Setting(name, impact.restitution)).impulse
        for name in jump_model_names(impact.jump_model or "crb")
    ]
    torque = np.max([np.abs(terms.J.T @ iota) for iota in impulses], axis=0) / impact.impact_duration
    wrench = np.max([np.abs(np.concatenate([iota, np.cross(contact - flange, iota)])) for iota in impulses], axis=0)
    impulse = max(impulses, key=np.linalg.norm)
    return ImpactPeaks(float(speed), float(impact.impact_duration), impulse, torque, wrench / impact.impact_duration)


@dataclass(frozen=True)
class CollisionThresholds:
    """The four lists ``set_collision_behavior`` takes (N m per joint, N and N m Cartesian) and
    the one line that says where they come from (``reason``)."""

    lower_torque: list[float]
    upper_torque: list[float]
    lower_force: list[float]
    upper_force: list[float]
    reason: str

    def to_dict(self) -> dict:
        return {
            "lower_torque_thresholds": self.lower_torque, "upper_torque_thresholds": self.upper_torque,
            "lower_force_thresholds": self.lower_force, "upper_force_thresholds": self.upper_force,
            "reason": self.reason,
        }


def fixed_thresholds(settings: RobotConfig) -> CollisionThresholds:
    """The table's lists, each left out the default."""
    given = [settings.lower_torque_thresholds, settings.upper_torque_thresholds]
    forces = [settings.lower_force_thresholds, settings.upper_force_thresholds]
    lists = [DEFAULT_TORQUE_THRESHOLDS if x is None else x for x in given]
    lists += [DEFAULT_FORCE_THRESHOLDS if x is None else x for x in forces]
    source = "the [libfranka] table's" if any(x is not None for x in given + forces) else "the [libfranka] defaults"
    return CollisionThresholds(*(list(map(float, x)) for x in lists), f"collision thresholds: {source}")


def scaled(peak: np.ndarray, factor: float, default: list[float], bound: float) -> np.ndarray:
    """min(bound, max(default, factor peak)) per entry."""
    return np.minimum(bound, np.maximum(np.asarray(default, dtype=float), factor * peak))


def impact_thresholds(settings: RobotConfig, peaks: ImpactPeaks | None) -> CollisionThresholds:
    """The thresholds the run sets (module docstring): from ``peaks`` when the table says
    ``from_impact`` and a run's impact is planned, else :func:`fixed_thresholds`."""
    if settings.collision_thresholds != FROM_IMPACT or peaks is None:
        return fixed_thresholds(settings)
    k = settings.impact_threshold_factor
    torque = scaled(peaks.torque, k, DEFAULT_TORQUE_THRESHOLDS, MAX_COLLISION_TORQUE)
    force = scaled(peaks.wrench, k, DEFAULT_FORCE_THRESHOLDS, MAX_COLLISION_FORCE)
    lists = []
    for computed, lower, upper in (
        (torque, settings.lower_torque_thresholds, settings.upper_torque_thresholds),
        (force, settings.lower_force_thresholds, settings.upper_force_thresholds),
    ):
        low = computed if lower is None else np.asarray(lower, dtype=float)
        high = np.maximum(computed, low) if upper is None else np.asarray(upper, dtype=float)
        lists += [low.tolist(), high.tolist()]
    reason = (
        f"collision thresholds from the predicted impact at {peaks.speed:.3f} m/s (impulse "
        f"{np.linalg.norm(peaks.impulse):.3g} N s over {1e3 * peaks.duration:.3g} ms: peak force "
        f"{np.linalg.norm(peaks.wrench[:3]):.0f} N, peak joint torque {np.max(peaks.torque):.0f} N m) times {k:g}, "
        f"within [the defaults, {MAX_COLLISION_FORCE:g}]: joint torques {_rounded(lists[1])} N m, "
        f"Cartesian {_rounded(lists[3])} N, N m"
    )
    if any(x is not None for x in (settings.lower_torque_thresholds, settings.upper_torque_thresholds,
                                   settings.lower_force_thresholds, settings.upper_force_thresholds)):
        reason += " (the [libfranka] table's lists where it gives them)"
    return CollisionThresholds(*lists, reason)


def _rounded(values: list[float]) -> str:
    return "[" + ", ".join(f"{x:.0f}" for x in values) + "]"
