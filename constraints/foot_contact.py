"""The feet of a kinematic-controlled humanoid held flat on the ground (equality rows)."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.whole_body_terms import WholeBodyTerms

from .constraint import Constraint, ControlCycle


class FootContact(Constraint):
    """Jf dv = -dJf v: the 6-D world-aligned twist of each foot frame keeps its value, so a
    foot standing still (zero twist) stays still ("the equivalent kinematic contact constraints
    of a kinematic-controlled robot", no slip and no lift). 12 equality rows (left foot, then
    right; linear, then angular), lower = upper, in acceleration units (m/s^2, rad/s^2).

    The feet's impulsive wrenches during a hand impact are those of the feet-held predictors
    (``floating_base``): bilateral, not checked against friction or the soles.
    """

    name = "foot_contact"
    rows = 12

    def compute_into(self, terms: WholeBodyTerms, cycle: ControlCycle, C, lower, upper) -> None:
        C[:] = terms.Jf
        np.negative(terms.dJf_dq, out=lower)
        upper[:] = lower
