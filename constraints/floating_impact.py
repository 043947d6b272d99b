"""The expected hand impact of the standing humanoid (``FloatingExpectedImpact``): the
floating-base predictors' maps of a state and the arm's activation rule.

The maps (``controller.model.jump`` in its held-contact form, docs/whole-body-qp.md) of the feet-held
predictors: the impulse iota = G J v-, the jump dv = A v- with A = K G J (crb (12), (20)-(21);
gm (12), (22)-(23); classical (5)-(6)) and the CoM velocity jump C iota. The activation rule is
``ExpectedImpact``'s (contact not leaving the surface, surface within the look-ahead distance or
time), which reads only the contact point, its Jacobian and the velocity, so it applies to the
nv velocities of the floating base unchanged.
"""

from __future__ import annotations

from impactqp.controller.model.floating_base import METHODS
from impactqp.controller.model.jump import JumpMatrices
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.whole_body_terms import WholeBodyTerms

from .impact_model import ExpectedImpact, normal_motion


class FloatingExpectedImpact(ExpectedImpact):
    """An expected hand impact on ``surface`` predicted with one floating-base method (crb by
    default, gm or classical); the maps and the activation are computed once per state
    (``WholeBodyTerms.stamp``) and shared by the whole-body impact constraints."""

    def __init__(self, surface: Surface, method: str = "crb", restitution: float = 0.0, **rule):
        if method not in METHODS:
            raise BadInputError(f"unknown floating-base jump model {method!r}; choose from {', '.join(METHODS)}")
        super().__init__(surface, method, restitution, **rule)
        self.method = method
        self._maps: JumpMatrices | None = None

    def matrices(self, terms: WholeBodyTerms) -> JumpMatrices:
        """G, A and C of this state."""
        self._update(terms)
        return self._maps

    def _update(self, terms: WholeBodyTerms) -> None:
        if terms.stamp == self._stamp:
            return
        normal = self.surface.normal
        self._maps = self.model.unit_matrices(terms, normal, self.restitution)
        self._active = self.always_active or self._rule(*normal_motion(terms.J, normal, terms.contact_point, terms.dq))
        self._stamp = terms.stamp
