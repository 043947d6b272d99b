"""One standing trial of a stance's search, read for the search (:class:`StanceEvaluation`), and
the search's result for one stance (:class:`StanceMaxSpeed`): the closed forms, the simulated
highest feasible speed, every trial and the checks at multiples of the closed form
(``max_speed_search.search_stance``, docs/max-speed.md)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from impactqp.sim.runner import NORMAL, WallNotReachedError
from impactqp.sim.trial_result import TrialResult
from impactqp.sim.trial_sources import QpRecord

WALL_NOT_REACHED = "wall not reached"
"""The failure of a standing trial whose hand never touched the wall."""


@dataclass(frozen=True)
class StanceEvaluation:
    """One simulated trial of the search: commanded and contact speed (m/s), what failed, each
    failed criterion's onset (s from the first contact) and, with the QP in the loop, the impact
    rows tight just before the contact (``QpRecord.binding``; "" without the QP), the number of
    its cycles not OK (``QpRecord.not_ok``; 0 without the QP) and the hand's speed target
    (``QpRecord.speed_target``, the governed asked speed; None without the QP)."""

    reference_speed: float
    contact_speed: float
    max_velocity_ratio: float
    foot_slip: float
    foot_lift: float
    fell: bool
    first_failure: str
    onsets: dict = field(default_factory=dict)
    binding: str = ""
    not_ok: int = 0
    speed_target: float | None = None

    @classmethod
    def of(cls, trial: TrialResult) -> StanceEvaluation:
        record = trial.record
        qp = isinstance(record, QpRecord)
        binding = ", ".join(record.binding(trial.impact.pre_index)) if qp else ""
        return cls(trial.normal_speed, trial.contact_speed, trial.max_velocity_ratio, trial.held.foot_slip, trial.held.foot_lift,
                   trial.fell, trial.first_failure, trial.failure_times, binding, record.not_ok if qp else 0,
                   record.speed_target if qp else None)

    @classmethod
    def of_speed(cls, run: Callable[[float], TrialResult], speed: float) -> StanceEvaluation:
        """The evaluation of ``run(speed)``, or, when the hand never reached the wall (a robot whose
        torques cannot bring it there at that speed), a failed one: no contact, ``WALL_NOT_REACHED``."""
        try:
            return cls.of(run(speed))
        except WallNotReachedError:
            return cls(speed, 0.0, 0.0, 0.0, 0.0, False, WALL_NOT_REACHED)

    @property
    def violated(self) -> bool:
        return bool(self.first_failure)

    def to_json(self) -> dict:
        return {
            "reference_speed": self.reference_speed, "contact_speed": self.contact_speed,
            "max_velocity_ratio": self.max_velocity_ratio, "foot_slip": self.foot_slip,
            "foot_lift": self.foot_lift, "fell": self.fell, "first_failure": self.first_failure,
            "violated": self.violated, "onsets": self.onsets, "binding": self.binding, "not_ok": self.not_ok,
            "speed_target": self.speed_target,
        }


@dataclass(frozen=True)
class StanceMaxSpeed:
    """Closed-form and simulated highest feasible speed of one stance."""

    stance: str
    q: np.ndarray
    predicted: dict  # method -> MaxSpeed
    simulated_reference: float  # highest feasible commanded speed (m/s)
    simulated_contact: float  # its measured contact speed (m/s)
    failed_first: str  # what failed first at the lowest infeasible commanded speed ("" if none)
    evaluations: list = field(default_factory=list)
    checks: dict = field(default_factory=dict)  # factor of the checks' reference -> StanceEvaluation at that asked speed

    def to_json(self) -> dict:
        return {
            "posture": self.stance,
            "q_impact": self.q.tolist(),
            "normal": NORMAL.tolist(),
            "predicted_max_speed": {m: p.to_json()["speed"] for m, p in self.predicted.items()},
            "binding": {m: {"criterion": p.criterion, "where": p.where} for m, p in self.predicted.items()},
            "bounds": {m: p.to_json()["bounds"] for m, p in self.predicted.items()},
            "simulated_max_speed": self.simulated_reference,
            "simulated_contact_speed": self.simulated_contact,
            "simulated_failed_first": self.failed_first,
            "evaluations": [e.to_json() for e in sorted(self.evaluations, key=lambda e: e.reference_speed)],
            "checks": {f"{factor:g}": e.to_json() for factor, e in self.checks.items()},
        }
