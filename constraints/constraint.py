"""Common interface of the QP constraints.

Every constraint bounds the decision variable of the QP, the joint acceleration ddq, by rows

    lower <= C ddq <= upper

written in ACCELERATION units (rad/s^2), so that all rows of the QP have comparable scales
(docs/qp-constraints.md: rows written as dt-scaled velocity bounds made the warm-started proxsuite
report false infeasibilities). A constraint whose ``C`` is ``None`` is a box on ddq (C = I).
A constraint has a fixed number of rows; when it does not apply in a cycle it returns infinite
bounds for them, so the QP keeps its dimensions and can stay warm-started.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from impactqp.controller.model.robot import ModelTerms


class ConstraintRows(NamedTuple):
    """Rows lower <= C ddq <= upper; C is None for a box on ddq."""

    C: np.ndarray | None
    lower: np.ndarray
    upper: np.ndarray


@dataclass(frozen=True)
class ControlCycle:
    """What a constraint needs to know about the current control cycle besides the model terms.

    ``acceleration_lower`` and ``acceleration_upper`` bound the accelerations reachable in this
    cycle: the acceleration limits intersected with the jerk limits around the previous
    command's acceleration, max(-ddq_max, ddq_prev - dddq_max dt) <= ddq <=
    min(ddq_max, ddq_prev + dddq_max dt). The joint-space box constraints clip their bounds into
    this interval, so that position, velocity and acceleration limits never conflict.

    ``horizon`` h = max(dt, max_i ddq_max_i / dddq_max_i) is the look-ahead that keeps general
    velocity rows recursively feasible under the jerk limits: if C (dq + ddq s) is within its
    bounds at s = 0 and s = h, then at the next cycle ddq' = (1 - dt / h) ddq is reachable (its
    change per joint is at most dt |ddq_i| / h <= dddq_max_i dt) and gives
    dq' + ddq' h = dq + ddq h: the same, feasible, value. By convexity the rows also hold at
    s = dt, i.e. for the commanded velocity dq_cmd = dq + ddq dt.
    """

    dt: float
    acceleration_lower: np.ndarray
    acceleration_upper: np.ndarray
    horizon: float

    @classmethod
    def after(cls, previous_ddq: np.ndarray, dt: float, ddq_max: np.ndarray, dddq_max: np.ndarray):
        step = dddq_max * dt
        return cls(
            dt,
            np.maximum(-ddq_max, previous_ddq - step),
            np.minimum(ddq_max, previous_ddq + step),
            max(dt, float(np.max(ddq_max / dddq_max))),
        )

    def recoverable(self, C: np.ndarray, lower: np.ndarray, upper: np.ndarray):
        """Rows lower <= C ddq <= upper relaxed, row by row, to what this cycle can reach.

        Over the reachable box of ddq, C_i ddq spans [r_i, R_i] with r_i = sum_j
        min(C_ij lo_j, C_ij hi_j) (R_i with max). A row that the state already violates
        (e.g. the contact approaches faster than the impact allows) cannot be met in one cycle;
        it becomes C_i ddq <= max(upper_i, r_i) (and >= min(lower_i, R_i)), i.e. it asks for the
        largest correction the acceleration and jerk limits allow, instead of making the QP
        infeasible. Rows that can be met are unchanged.
        """
        low = C * self.acceleration_lower
        high = C * self.acceleration_upper
        reach_min = np.minimum(low, high).sum(axis=1)
        reach_max = np.maximum(low, high).sum(axis=1)
        return np.minimum(lower, reach_max), np.maximum(upper, reach_min)

    def clip_to_reachable(self, lower: np.ndarray, upper: np.ndarray):
        """(lower, upper) clipped into the reachable acceleration interval, in place."""
        lo, hi = self.acceleration_lower, self.acceleration_upper
        np.minimum(np.maximum(lower, lo, out=lower), hi, out=lower)
        np.minimum(np.maximum(upper, lo, out=upper), hi, out=upper)
        return lower, upper


class Constraint:
    """A named set of ``rows`` linear rows on ddq (acceleration units)."""

    name: str = ""
    rows: int = 0
    is_box: bool = False

    def compute(self, terms: ModelTerms, cycle: ControlCycle) -> ConstraintRows:
        raise NotImplementedError
