"""Common interface of the QP constraints.

Every constraint bounds the decision variable of the QP, the joint acceleration ddq, by rows

    lower <= C ddq <= upper

written in ACCELERATION units (rad/s^2), so that all rows of the QP have comparable scales
(docs/qp-constraints.md, Decision variable and units). A constraint whose ``C`` is ``None`` is a
box on ddq (C = I).
A constraint has a fixed number of rows; when it does not apply in a cycle it returns infinite
bounds for them, so the QP keeps its dimensions and can stay warm-started.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from numba import njit

from impactqp.controller.model.model_terms import ModelTerms


class ConstraintRows(NamedTuple):
    """Rows lower <= C ddq <= upper; C is None for a box on ddq."""

    C: np.ndarray | None
    lower: np.ndarray
    upper: np.ndarray


@dataclass(eq=False)
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

    A controller keeps one ControlCycle and moves it forward in place (``advance``).
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

    def advance(self, previous_ddq: np.ndarray, ddq_max: np.ndarray, jerk_step: np.ndarray) -> None:
        """The reachable interval of the next cycle (``after``), written in place;
        ``jerk_step`` = dddq_max dt."""
        reachable_interval(previous_ddq, ddq_max, jerk_step, self.acceleration_lower, self.acceleration_upper)

    def recoverable(self, C: np.ndarray, lower: np.ndarray, upper: np.ndarray):
        """Rows lower <= C ddq <= upper relaxed, row by row, to what this cycle can reach.

        Over the reachable box of ddq, C_i ddq spans [r_i, R_i] with r_i = sum_j
        min(C_ij lo_j, C_ij hi_j) (R_i with max). A row that the state already violates
        (e.g. the contact approaches faster than the impact allows) cannot be met in one cycle;
        it becomes C_i ddq <= max(upper_i, r_i) (and >= min(lower_i, R_i)), i.e. it asks for the
        largest correction the acceleration and jerk limits allow, instead of making the QP
        infeasible. Rows that can be met are unchanged. With the box's centre c and half-width
        w, r = C c - |C| w and R = C c + |C| w. ``lower`` and ``upper`` are relaxed in place.
        """
        relax_to_reachable(C, lower, upper, self.acceleration_lower, self.acceleration_upper)
        return lower, upper

    def clip_to_reachable(self, lower: np.ndarray, upper: np.ndarray):
        """(lower, upper) clipped into the reachable acceleration interval, in place."""
        lo, hi = self.acceleration_lower, self.acceleration_upper
        np.minimum(np.maximum(lower, lo, out=lower), hi, out=lower)
        np.minimum(np.maximum(upper, lo, out=upper), hi, out=upper)
        return lower, upper


class Constraint:
    """A named set of ``rows`` linear rows on ddq (acceleration units).

    A constraint writes its rows into arrays it is given (``compute_into``): a controller hands
    it views of the stacked QP data, so nothing is copied. Where a class has a compiled kernel
    (numba), ``compute_into`` calls it (its plain-numpy statement is in the tests,
    ``tests/reference/constraints.py``), and its ``kernel_parameters`` give that kernel's
    parameters in one flat array, the form a controller's compiled cycle plan reads
    (``controller.qp.cycle_plan``). Box bounds are then clipped into the
    cycle's reachable accelerations (``ControlCycle.clip_to_reachable``) and the rows of a
    ``relaxed`` constraint, which the state may already violate, are relaxed to the largest
    correction the cycle allows (``ControlCycle.recoverable``); the controller does both for all
    constraints at once, ``compute`` does them for one.
    """

    name: str = ""
    rows: int = 0
    is_box: bool = False
    relaxed: bool = False
    parameter_edits = 0
    """Assignments to the attributes of any constraint so far: a compiled cycle plan
    (``controller.qp.cycle_plan``) packs its constraints' ``kernel_parameters`` again when it
    changed (a parameter is set by assignment; an array changed in place is not seen)."""

    def __setattr__(self, name: str, value) -> None:
        object.__setattr__(self, name, value)
        Constraint.parameter_edits += 1

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower: np.ndarray, upper: np.ndarray) -> None:
        """Write the raw rows of this state: C (rows x number of velocities; None for a box), lower
        and upper."""
        raise NotImplementedError

    def compute(self, terms: ModelTerms, cycle: ControlCycle) -> ConstraintRows:
        """The rows of this state in new arrays, clipped or relaxed as the class says."""
        n = cycle.acceleration_lower.shape[0]  # the number of velocities; a box bounds each
        size = n if self.is_box else self.rows
        C = None if self.is_box else np.empty((self.rows, n))
        lower, upper = np.empty(size), np.empty(size)
        self.compute_into(terms, cycle, C, lower, upper)
        if self.is_box:
            cycle.clip_to_reachable(lower, upper)
        elif self.relaxed:
            cycle.recoverable(C, lower, upper)
        return ConstraintRows(C, lower, upper)


@njit(cache=True)
def symmetric_row_bounds(C, dq, limit, inv_h, active, lower, upper):
    """Kernel shared by the impact-aware constraint kernels (C already written): the bounds of
    the rows C ddq that keep |C (dq + h ddq)| <= limit, (+-limit - C dq) / h, when the rows are
    ``active``; unbounded otherwise."""
    for i in range(C.shape[0]):
        if not active:
            lower[i] = -np.inf
            upper[i] = np.inf
            continue
        centre = 0.0
        for j in range(C.shape[1]):
            centre += C[i, j] * dq[j]
        lower[i] = (-limit[i] - centre) * inv_h
        upper[i] = (limit[i] - centre) * inv_h


@njit(cache=True)
def relax_to_reachable(C, lower, upper, lo, hi):
    """Kernel of ``ControlCycle.recoverable``: row i spans [c_i - s_i, c_i + s_i] over the box
    [lo, hi], c_i = C_i (lo + hi) / 2 and s_i = |C_i| (hi - lo) / 2; lower_i <= c_i + s_i and
    upper_i >= c_i - s_i after it, in place."""
    for i in range(C.shape[0]):
        centre = 0.0
        spread = 0.0
        for j in range(C.shape[1]):
            centre += C[i, j] * 0.5 * (lo[j] + hi[j])
            spread += abs(C[i, j]) * 0.5 * (hi[j] - lo[j])
        lower[i] = min(lower[i], centre + spread)
        upper[i] = max(upper[i], centre - spread)


@njit(cache=True)
def reachable_interval(previous_ddq, ddq_max, jerk_step, lower, upper):
    """Kernel of ``ControlCycle.advance``: max(-ddq_max, ddq_prev - step) <= ddq <=
    min(ddq_max, ddq_prev + step)."""
    for i in range(previous_ddq.shape[0]):
        lower[i] = max(-ddq_max[i], previous_ddq[i] - jerk_step[i])
        upper[i] = min(ddq_max[i], previous_ddq[i] + jerk_step[i])
