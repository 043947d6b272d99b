"""A validated impact query and the report of all predictors for it.

An :class:`ImpactQuery` is a posture q, the unit surface normal n (towards the robot), the
pre-impact contact velocity v- = -speed n + v_t (v_t orthogonal to n), the restitution c_r and,
for a frictional impact, the Coulomb coefficient mu and the restitution model
(``controller.model.frictional_impact``). It is checked once on construction: bad values raise
``BadInputError`` with a clear message.

Without friction each predictor's impulse is eq. (12) (the classical ones: eq. (5)); with
friction, every predictor's inverse inertia W (the classical's: W_gm = J M^-1 J^T) gives the 3-D
frictional impulse, and the predictor's own map gives the jump (dq+ = dq- + J^+ W iota for CRB
and GM, M^-1 J^T iota for the classical). ``classical_normal`` keeps only the normal part of the
classical impulse, which a frictional impulse has no use for: it is left out with friction.

A robot on held contacts (the standing G1, docs/floating-base.md) takes the same law with the
W of its held-contact maps (W_gm = J P_f J^T for classical and GM, W_crb of the locked robot for
CRB) and its own jump map (P_f J^T iota, or J# W iota), which keeps the held contacts still:
:func:`method_prediction` serves both.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .frictional_impact import RESTITUTION_MODELS, frictional_impulse
from .jump import JUMP_MODELS, METHODS, gm_inverse_inertia
from .robot import PandaModel
from .validation import BadInputError, approach_speed, finite_vector, name_in, number_in_range, tangential_velocity
from .validation import restitution as restitution_coefficient
from .validation import unit_normal

FRICTIONAL_METHODS = tuple(m for m in METHODS if m != "classical_normal")
"""The predictors a frictional impact serves (module docstring)."""


def inverse_inertia(method: str, terms, normal: np.ndarray, restitution: float = 0.0) -> np.ndarray:
    """The predictor ``method``'s inverse inertia W at the contact (3 x 3): its own (CRB, GM),
    the classical's W_gm = J M^-1 J^T (module docstring)."""
    W = JUMP_MODELS[method].maps(terms, normal, restitution).W
    return gm_inverse_inertia(terms) if W is None else W


@lru_cache(maxsize=1)
def default_robot() -> PandaModel:
    return PandaModel()


@dataclass(frozen=True)
class ImpactQuery:
    q: np.ndarray
    normal: np.ndarray
    pre_impact_velocity: np.ndarray
    restitution: float
    friction: float | None = None
    restitution_model: str = "energetic"

    @classmethod
    def from_speed(cls, q, normal, speed: float, tangential=None, restitution: float = 0.0,
                   friction: float | None = None, restitution_model: str = "energetic"):
        """v- = -speed * n + tangential, with n normalised and tangential orthogonal to n; a
        frictional impact with ``friction`` mu (None: frictionless, eq. (12))."""
        normal = unit_normal(normal)
        speed = approach_speed(speed)
        c_r = restitution_coefficient(restitution)
        tangential = np.zeros(3) if tangential is None else tangential_velocity(tangential, normal)
        if friction is not None:
            friction = number_in_range(friction, 0.0, 10.0, "the friction coefficient --friction", "")
        name_in(restitution_model, RESTITUTION_MODELS, "the restitution model")
        q = finite_vector(q, None, "the joint positions q")
        return cls(q, normal, -speed * normal + tangential, c_r, friction, restitution_model)


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
    if query.friction is not None:
        report["friction"], report["restitution_model"] = query.friction, query.restitution_model
        methods = [name for name in methods if name in FRICTIONAL_METHODS]
        if not methods:
            raise BadInputError(f"--method classical_normal has no frictional form; choose from {', '.join(FRICTIONAL_METHODS)}")
    for name in methods:
        pred, impact = method_prediction(name, terms, query)
        entry = {"dq_jump": pred.dq_jump.tolist(), "impulse": pred.impulse.tolist()}
        if pred.W is not None:
            entry["W"] = pred.W.tolist()
        report["methods"][name] = entry | frictional_entry(impact)
    return report


def method_prediction(name: str, terms, query: ImpactQuery):
    """The predictor ``name``'s ``JumpPrediction`` at the state ``terms`` (a fixed base, or a
    robot on held contacts: then also the held contacts' impulse and the CoM jump) and, for a
    frictional ``query``, its ``FrictionalImpact`` (module docstring; None without friction)."""
    impact = None
    if query.friction is not None:
        W = inverse_inertia(name, terms, query.normal, query.restitution)
        impact = frictional_impulse(W, query.normal, query.pre_impact_velocity, query.friction,
                                    query.restitution, query.restitution_model)
    pred = JUMP_MODELS[name].predict(terms, query.normal, query.pre_impact_velocity, query.restitution,
                                     None if impact is None else impact.impulse)
    return pred, impact


def frictional_entry(impact) -> dict:
    """A report entry's frictional keys: the mode, mu_bar and the post-impact contact velocity
    (none without friction)."""
    if impact is None:
        return {}
    return {"mode": impact.mode, "mu_bar": impact.mu_bar, "post_impact_contact_velocity": impact.post_velocity.tolist()}
