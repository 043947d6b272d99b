"""The held contacts of a robot standing on them (a humanoid's soles): equality rows."""

from __future__ import annotations

import numpy as np

from .constraint import Constraint, ControlCycle


class HeldContactRows(Constraint):
    """Jf dv = -dJf v, Jf the held contacts' Jacobian (the terms' ``held_jacobian``, dJf v their
    ``held_drift``): the 6-D world-aligned twist of each held contact frame keeps its value, so a
    foot standing still (zero twist) stays still ("the equivalent kinematic contact constraints
    of a kinematic-controlled robot", no slip and no lift). One block of 6 equality rows per held
    contact (the order of the terms: for the G1 the left foot, then the right; linear, then
    angular), lower = upper, in acceleration units (m/s^2, rad/s^2).

    The held contacts' impulsive wrenches during an impact are those of the held-contact jump
    maps (``controller.model.jump``): bilateral, not checked against friction or the soles.
    """

    name = "held_contacts"

    def __init__(self, rows: int):
        self.rows = rows

    def kernel_parameters(self) -> np.ndarray:
        """None: the rows are the terms' (a compiled cycle plan's kernel copies them)."""
        return np.empty(0)

    def compute_into(self, terms, cycle: ControlCycle, C, lower, upper) -> None:
        C[:] = terms.held_jacobian
        np.negative(terms.held_drift, out=lower)
        upper[:] = lower
