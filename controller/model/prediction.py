"""A validated impact query and the report of all predictors for it.

An :class:`ImpactQuery` is a posture q, the unit surface normal n (towards the robot), the
pre-impact contact velocity v- = -speed n + v_t (v_t orthogonal to n) and the restitution c_r.
It is checked once on construction: bad values raise ``ValueError`` with a clear message.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .jump import JUMP_MODELS, METHODS
from .robot import PandaModel
from .validation import approach_speed, finite_vector, tangential_velocity, unit_normal
from .validation import restitution as restitution_coefficient

@lru_cache(maxsize=1)
def default_robot() -> PandaModel:
    return PandaModel()


@dataclass(frozen=True)
class ImpactQuery:
    q: np.ndarray
    normal: np.ndarray
    pre_impact_velocity: np.ndarray
    restitution: float

    @classmethod
    def from_speed(cls, q, normal, speed: float, tangential=None, restitution: float = 0.0):
        """v- = -speed * n + tangential, with n normalised and tangential orthogonal to n."""
        normal = unit_normal(normal)
        speed = approach_speed(speed)
        c_r = restitution_coefficient(restitution)
        tangential = np.zeros(3) if tangential is None else tangential_velocity(tangential, normal)
        return cls(finite_vector(q, None, "the joint positions q"), normal, -speed * normal + tangential, c_r)


def predict_all(query: ImpactQuery, methods=METHODS, robot: PandaModel | None = None) -> dict:
    """JSON-ready report of the chosen predictors at the query (the `predict` contract)."""
    robot = robot or default_robot()
    terms = robot.terms(query.q)
    report = {
        "q": terms.q.tolist(),
        "contact_point": terms.contact_point.tolist(),
        "normal": query.normal.tolist(),
        "pre_impact_velocity": query.pre_impact_velocity.tolist(),
        "restitution": query.restitution,
        "cond_M": terms.cond_M,
        "methods": {},
    }
    for name in methods:
        pred = JUMP_MODELS[name].predict(terms, query.normal, query.pre_impact_velocity, query.restitution)
        entry = {"dq_jump": pred.dq_jump.tolist(), "impulse": pred.impulse.tolist()}
        if pred.W is not None:
            entry["W"] = pred.W.tolist()
        report["methods"][name] = entry
    return report
