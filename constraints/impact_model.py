"""The impact the impact-aware constraints prepare for: surface, jump model and activation rule.

Jump prediction (docs/qp-constraints.md). With the pre-impact velocity dq- = dq + ddq dt, the
chosen predictor (``controller.model.jump``) gives an impulse iota = G J dq- and a joint-velocity jump
ddq_jump = K iota = A dq-, A = K G J, both linear in dq-:

    crb        (12), (20)-(21)   G = -(1+c_r) n n^T / (n^T W_crb n),   K = J+ W_crb
    gm         (12), (22)-(23)   G = -(1+c_r) n n^T / (n^T W_gm n),    K = J+ W_gm
    classical  (5)-(6)           G = -(1+c_r) (J M^-1 J^T)^-1,         K = M^-1 J^T

The post-impact velocity is dq+ = (I + A) dq- and the impulsive joint torque over the impact
duration delta_t is J^T iota / delta_t = P dq- / delta_t with P = J^T G J.

Activation rule
---------------
The constraints only describe an impact that is about to happen. They are active in a cycle
when the contact point is not leaving the surface (normal velocity n.v <= release_speed, with
v = J dq) and the surface is near: the signed distance d of the contact point satisfies
d <= lookahead_distance, or d <= lookahead_time * max(-n.v, 0) (the impact would come within
lookahead_time at the current speed). ``always_active=True`` bypasses the rule. Because one
cycle changes the contact velocity by at most |J| ddq_max dt (a few mm/s), a cycle in which the
rule says inactive cannot command a dangerous approach speed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from impactqp.controller.model.jump import GeneralizedMomentumJump, JumpModel, jump_model
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import ModelTerms
from impactqp.controller.model import validation
from impactqp.controller.model.validation import BadInputError

MAX_LOOKAHEAD_DISTANCE, MAX_LOOKAHEAD_TIME = 1.0, 10.0
"""m and s: the impact-aware constraints switch on within a metre or ten seconds of the surface."""

JUMP_MODEL_CHOICES = {
    "crb": ("crb",),
    "gm": ("gm",),
    "classical": ("classical",),
    "classical_normal": ("classical_normal",),
    "robust": ("crb", "gm", "classical"),
}
"""Jump-model settings of the impact-aware constraints; 'robust' satisfies crb, gm and
classical at once."""


def jump_model_names(choice: str) -> tuple[str, ...]:
    try:
        return JUMP_MODEL_CHOICES[choice]
    except KeyError:
        raise BadInputError(
            f"unknown jump model {choice!r}; choose from {', '.join(JUMP_MODEL_CHOICES)}"
        ) from None


class ImpactMaps(NamedTuple):
    """Linear maps of one state: dq_jump = jump_matrix dq-, J^T iota = torque_matrix dq-;
    ``active`` is the activation rule's answer for that state."""

    jump_matrix: np.ndarray
    torque_matrix: np.ndarray
    active: bool


class ImpactModel:
    """An expected impact on ``surface`` predicted with one jump model."""

    def __init__(
        self,
        surface: Surface,
        jump_model_name: str = "crb",
        restitution: float = 0.0,
        lookahead_distance: float = 0.10,
        lookahead_time: float = 0.30,
        release_speed: float = 0.02,
        always_active: bool = False,
    ):
        self.surface = surface
        self.model: JumpModel = jump_model(jump_model_name)
        self.restitution = validation.restitution(restitution)
        self.lookahead_distance = validation.number_in_range(
            lookahead_distance, 0.0, MAX_LOOKAHEAD_DISTANCE, "the look-ahead distance", "m"
        )
        self.lookahead_time = validation.number_in_range(lookahead_time, 0.0, MAX_LOOKAHEAD_TIME, "the look-ahead time", "s")
        self.release_speed = validation.number_in_range(
            release_speed, 0.0, validation.MAX_CONTACT_SPEED, "the release speed", "m/s"
        )
        self.always_active = validation.boolean(always_active, "always_active")
        self._surface_offset = float(surface.normal @ surface.point)  # n.s: distance = n.p - n.s
        self._stamp = 0  # ModelTerms.stamp of the cached maps
        self._maps: ImpactMaps | None = None

    @property
    def name(self) -> str:
        return self.model.name

    def is_active(self, terms: ModelTerms) -> bool:
        """The activation rule of the module docstring."""
        if self.always_active:
            return True
        normal = self.surface.normal
        return self._rule(float(normal @ (terms.J @ terms.dq)), float(normal @ terms.contact_point))

    def _rule(self, normal_speed: float, normal_position: float) -> bool:
        """The rule from n.v and n.p (the distance is n.p - n.s)."""
        if normal_speed > self.release_speed:
            return False
        distance = normal_position - self._surface_offset
        return distance <= max(self.lookahead_distance, -normal_speed * self.lookahead_time)

    def maps(self, terms: ModelTerms) -> ImpactMaps:
        """A, P and the activation of this state; computed once per fill of ``terms``
        (``ModelTerms.stamp``) and shared by the constraints and the controller's prediction."""
        if terms.stamp != self._stamp:
            normal = self.surface.normal
            if isinstance(self.model, GeneralizedMomentumJump):
                jump_matrix, torque_matrix, normal_speed, normal_position = self._normal_impulse_maps(terms)
            else:
                maps = self.model.unit_maps(terms, normal, self.restitution)  # both checked once, above
                GJ = maps.G @ terms.J
                jump_matrix, torque_matrix = maps.K @ GJ, terms.J.T @ GJ
                normal_speed, normal_position = float(normal @ (terms.J @ terms.dq)), float(normal @ terms.contact_point)
            active = self.always_active or self._rule(normal_speed, normal_position)
            self._maps = ImpactMaps(jump_matrix, torque_matrix, active)
            self._stamp = terms.stamp
        return self._maps

    def _normal_impulse_maps(self, terms: ModelTerms):
        """A and P of the normal-impulse models (12) as rank-one products.

        G = s n n^T with s = -(1+c_r) / (n^T W n) and K = J+ W = J^T (J J^T)^-1 W (17), (21),
        (23), so A = K G J = s (J^T (J J^T)^-1 W n)(J^T n)^T and P = J^T G J = s (J^T n)(J^T n)^T.
        """
        n = terms.J.shape[1]
        jump_matrix, torque_matrix = np.empty((n, n)), np.empty((n, n))
        normal = self.surface.normal
        normal_speed, normal_position = rank_one_impulse_maps(
            terms.J, terms.JJt_inv, self.model.inverse_inertia_times(terms, normal), normal, terms.contact_point,
            terms.dq, self.restitution, jump_matrix, torque_matrix,
        )
        return jump_matrix, torque_matrix, normal_speed, normal_position

    def reference_normal_impulse_maps(self, terms: ModelTerms):
        """``_normal_impulse_maps`` in plain numpy (the reference of its kernel)."""
        normal = self.surface.normal
        Jt_normal = normal @ terms.J
        W_normal = self.model.inverse_inertia_times(terms, normal)
        s = -(1.0 + self.restitution) / float(normal @ W_normal)
        jump_direction = terms.J.T @ (terms.JJt_inv @ (s * W_normal))
        return (
            jump_direction[:, None] * Jt_normal, (s * Jt_normal)[:, None] * Jt_normal,
            float(Jt_normal @ terms.dq), float(normal @ terms.contact_point),
        )


@njit(cache=True)
def rank_one_impulse_maps(J, JJt_inv, W_normal, normal, contact_point, dq, restitution, jump_matrix, torque_matrix):
    """Kernel of ``ImpactModel._normal_impulse_maps``: A = s (J^T (J J^T)^-1 W n)(J^T n)^T and
    P = s (J^T n)(J^T n)^T with s = -(1+c_r) / (n^T W n); returns n.(J dq) and n.p, the inputs
    of the activation rule."""
    s = -(1.0 + restitution) / (normal[0] * W_normal[0] + normal[1] * W_normal[1] + normal[2] * W_normal[2])
    y = JJt_inv @ (s * W_normal)
    direction = J.T @ y
    Jt_normal = normal @ J
    normal_speed = 0.0
    for j in range(J.shape[1]):
        normal_speed += Jt_normal[j] * dq[j]
    normal_position = normal[0] * contact_point[0] + normal[1] * contact_point[1] + normal[2] * contact_point[2]
    for i in range(J.shape[1]):
        for j in range(J.shape[1]):
            jump_matrix[i, j] = direction[i] * Jt_normal[j]
            torque_matrix[i, j] = s * Jt_normal[i] * Jt_normal[j]
    return normal_speed, normal_position
