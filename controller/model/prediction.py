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

ORTHOGONALITY_TOLERANCE = 1e-6


def is_tangential(velocity: np.ndarray, normal: np.ndarray) -> bool:
    """True when ``velocity`` is orthogonal to the unit ``normal`` (to ORTHOGONALITY_TOLERANCE)."""
    return abs(velocity @ normal) <= ORTHOGONALITY_TOLERANCE * max(1.0, float(np.linalg.norm(velocity)))


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
        normal = np.asarray(normal, dtype=float)
        if normal.shape != (3,) or not np.all(np.isfinite(normal)):
            raise ValueError("the normal must be 3 finite numbers")
        norm = np.linalg.norm(normal)
        if norm < 1e-9:
            raise ValueError("the normal must not be zero")
        normal = normal / norm
        if not (np.isfinite(speed) and speed > 0.0):
            raise ValueError(f"the approach speed must be > 0 m/s, got {speed}")
        if not (np.isfinite(restitution) and 0.0 <= restitution <= 1.0):
            raise ValueError(f"the restitution must lie in [0, 1], got {restitution}")
        tangential = np.zeros(3) if tangential is None else np.asarray(tangential, dtype=float)
        if tangential.shape != (3,) or not np.all(np.isfinite(tangential)):
            raise ValueError("the tangential velocity must be 3 finite numbers")
        if not is_tangential(tangential, normal):
            raise ValueError(
                f"the tangential velocity must be orthogonal to the normal (t.n = {tangential @ normal:.3g})"
            )
        return cls(np.asarray(q, dtype=float), normal, -speed * normal + tangential, float(restitution))


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
