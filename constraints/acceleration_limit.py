"""Joint acceleration and jerk limits (Franka datasheet, docs/predictors.md, Conventions)."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle


class AccelerationLimit(Constraint):
    """|ddq| <= ddq_max and |ddq - ddq_prev| <= dddq_max dt (box on ddq).

    ddq_prev is the acceleration of the previous command, so consecutive commands respect the
    jerk limits. The interval is the cycle's reachable set (:class:`ControlCycle`); it is never
    empty because ddq_prev itself satisfies the acceleration limits. Its bounds are the cycle's,
    one per velocity.
    """

    name = "joint_acceleration_limit"
    is_box = True

    def kernel_parameters(self) -> np.ndarray:
        """None: its bounds are the cycle's."""
        return np.empty(0)

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        lower[:] = cycle.acceleration_lower
        upper[:] = cycle.acceleration_upper
