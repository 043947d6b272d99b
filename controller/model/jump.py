"""Impact-induced joint-velocity jump predictors (Wang, Dehio, Kheddar, RA-L 2022).

Every predictor is linear in the pre-impact contact velocity v-. It is written as two maps:

- the *impulse map* G (3x3): iota = G v-, the task-space impulse acting on the robot;
- the *impulse-to-jump map* K (7x3): ddq = K iota, the joint-velocity jump caused by iota.

so that ddq = K G v- and, with v- = J dq-, ddq = A dq- with the rank-deficient jump matrix
A = K G J used by the impact-aware constraints of the controller (docs/predictors.md), beside
the impulse-torque matrix P = J^T G J (J^T iota = P dq-): ``JumpModel.matrices``. For the
normal-impulse models (12), G = s n n^T makes both rank one:
A = s (J+ W n)(J^T n)^T and P = s (J^T n)(J^T n)^T, s = -(1+c_r) / (n^T W n).
A measured impulse iota° replaces G v-: ddq = K iota°.

=====================  =====================================  ==============================
predictor              impulse map G                          impulse-to-jump map K
=====================  =====================================  ==============================
classical (5)-(6)      -(1+c_r) W_gm^-1                       M^-1 J^T
classical_normal       -(1+c_r) n n^T W_gm^-1 (Sec. VI)       M^-1 J^T
gm (12), (22)-(23)     -(1+c_r) n n^T / (n^T W_gm n)          J+ W_gm
crb (12), (20)-(21)    -(1+c_r) n n^T / (n^T W_crb n)         J+ W_crb
=====================  =====================================  ==============================

with W_gm = J M^-1 J^T (22), J+ = J^T (J J^T)^-1 (17), and the composite-rigid-body inverse
inertia W_crb = (1/m) I3 - [r]x I_c^-1 [r]x (20), r = p - c from the centre of mass c of the
locked robot to the contact point p. The CRB path never forms or inverts M (a prediction from q
is one compiled call, ``jump_kernels.crb_jump``, on terms of one world-frame CRBA pass); the GM
and classical paths use M^-1 from Pinocchio's ``computeMinverse`` (``ModelTerms.M_inv``).

Held contacts. A robot standing on held contacts (a humanoid's soles, Jacobian Jf, kept still
through the impact: M dv = J^T iota + Jf^T lambda, Jf dv = 0) has the same predictors with the
constrained inverse inertia P_f = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 in place of M^-1
(W_gm = J P_f J^T, K = P_f J^T for the classical model) and the held-contact right inverse
J# = N J^T (J N J^T)^-1 in place of J+ (N the projector onto the null space of Jf), W_crb that of
the whole robot with every joint locked; the centre of mass then jumps by C iota,
C = Jcom P_f J^T (docs/whole-body-qp.md). A fixed-base arm is the case of no held contact
(Jf with no rows): P_f = M^-1, J# = J+, the table above.

The held contacts' impulse is lambda = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T iota (a wrench per held
contact, world axes about its frame), what keeps them still under iota.

This module is the one home of these maps and predictors: ``JumpModel`` gives them for one state
of any robot (``ModelTerms``; ``unit_maps`` and ``unit_matrices`` read the terms'
``held_jacobian``), :func:`predict` by a method's name (the same maps for N states of an arm at once are
``controller.model.batch.predict_from_terms``, on its batched terms, leading axis N); the
compiled kernels are in ``jump_kernels`` (the classical one in ``classical_matrices``). The
held-contact ``unit_maps`` read M^-1 and take J# = N (J N)^+, equal to N J^T (J N J^T)^-1; the
held-contact ``unit_matrices`` (a controller's every cycle) read the terms' M^-1 in one compiled
call.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from . import validation
from .classical_matrices import classical_jump_matrices
from .jump_kernels import (
    HELD_CONTACT_METHODS,
    crb_inverse_inertia_times,
    crb_jump,
    crb_maps,
    held_contact_maps,
    rank_one_jump_matrices,
)
from .model_terms import ModelTerms
from .term_fills import SingularPostureError
from .validation import BadInputError, finite_vector, unit_normal

METHODS = ("classical", "classical_normal", "gm", "crb")


def skew(v: np.ndarray) -> np.ndarray:
    """[v]x, the matrix of the cross product v x (of each vector along the last axis)."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def crb_inverse_inertia(terms: ModelTerms) -> np.ndarray:
    """W_crb = (1/m) I3 - [r]x I_c^-1 [r]x, eq. (20), in world axes.

    m is the moving mass of the locked (composite-rigid-body) robot, I_c its rotational inertia
    about its centre of mass and r the vector from the centre of mass to the contact point.
    It is the contact-point inverse inertia of the whole robot welded into one free rigid body:
    the arm with its base fixed, or the standing humanoid with every joint locked (terms with
    ``contact_point``, ``com``, ``mass`` and ``inertia_com``). For batched terms (leading axis N)
    it is the (N, 3, 3) stack.
    """
    r_hat = skew(terms.contact_point - terms.com)
    return np.eye(3) / terms.mass - r_hat @ np.linalg.solve(terms.inertia_com, r_hat)


def held_inverse_inertia_times_Jf_t(terms: ModelTerms) -> np.ndarray:
    """M^-1 Jf^T."""
    return terms.cached("MiJf", lambda: terms.M_inv @ terms.held_jacobian.T)


def constrained_inverse_inertia(terms: ModelTerms) -> np.ndarray:
    """P_f = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 (module docstring): dv = P_f tau_impulse
    with the held contacts kept still; M^-1 without held contacts."""

    def build():
        Mi = terms.M_inv
        if terms.held_jacobian.shape[0] == 0:
            return Mi
        MiJf = held_inverse_inertia_times_Jf_t(terms)
        P = Mi - MiJf @ held_gram_solve(terms.held_jacobian @ MiJf, MiJf.T)
        return 0.5 * (P + P.T)

    return terms.cached("P", build)


def joint_space_inverse_inertia_times_Jt(terms: ModelTerms) -> np.ndarray:
    """P_f J^T (nv x 3): M^-1 J^T without held contacts, P_f J^T with them."""
    if terms.held_jacobian.shape[0] == 0:
        return terms.M_inv @ terms.J.T
    return constrained_inverse_inertia(terms) @ terms.J.T


def held_pinv(terms: ModelTerms) -> np.ndarray:
    """J# = N (J N)^+ (nv x 3), N the projector onto null(Jf): the least-norm dv with J dv = x
    and Jf dv = 0 (J+ without held contacts)."""
    if terms.held_jacobian.shape[0] == 0:
        return terms.J_pinv

    def build():
        Jf = terms.held_jacobian
        N = np.eye(terms.M.shape[0]) - np.linalg.pinv(Jf) @ Jf
        return N @ np.linalg.pinv(terms.J @ N)

    return terms.cached("Jsharp", build)


def held_impulse(terms: ModelTerms, impulse: np.ndarray) -> np.ndarray:
    """lambda = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T iota (6 per held contact; none without)."""
    if terms.held_jacobian.shape[0] == 0:
        return np.zeros(0)
    MiJf = held_inverse_inertia_times_Jf_t(terms)
    return -held_gram_solve(terms.held_jacobian @ MiJf, MiJf.T @ (terms.J.T @ impulse))


def held_gram_solve(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(Jf M^-1 Jf^T)^-1 rhs for gram = Jf M^-1 Jf^T; SingularPostureError when it is singular
    (the held contacts' Jacobian loses rank at this state)."""
    try:
        return np.linalg.solve(gram, rhs)
    except np.linalg.LinAlgError:
        raise SingularPostureError("the held contacts' Jacobian is singular at this state") from None


def gm_inverse_inertia(terms: ModelTerms) -> np.ndarray:
    """W_gm = J P_f J^T, eq. (22): the generalized-momentum inverse inertia at the contact
    (J M^-1 J^T without held contacts)."""
    W = terms.J @ joint_space_inverse_inertia_times_Jt(terms)
    return 0.5 * (W + W.T)


def normal_impulse_map(W: np.ndarray, normal: np.ndarray, restitution: float) -> np.ndarray:
    """G = -(1+c_r) n n^T / (n^T W n): iota = G v- is the impulse of eq. (12) along n."""
    return -(1.0 + restitution) * np.outer(normal, normal) / float(normal @ W @ normal)


@dataclass(frozen=True)
class JumpPrediction:
    """One predictor's answer: the generalized-velocity jump ``dq_jump`` (nv), the contact
    impulse on the robot (3), W if any, the held contacts' impulse ``held_impulse`` lambda (6
    per held contact, none without) and the centre of mass's velocity jump ``com_jump``
    Jcom dq_jump (3; None without held contacts)."""

    method: str
    dq_jump: np.ndarray
    impulse: np.ndarray
    W: np.ndarray | None
    held_impulse: np.ndarray = field(default_factory=lambda: np.zeros(0))
    com_jump: np.ndarray | None = None


@dataclass(frozen=True)
class JumpMaps:
    """The maps of one predictor at one state: iota = G v- and ddq = K iota (module docstring);
    W is the predictor's inverse inertia at the contact (None for the classical ones)."""

    G: np.ndarray
    K: np.ndarray
    W: np.ndarray | None


class JumpMatrices(NamedTuple):
    """The maps of one predictor at one state in joint space: the jump dq_jump = jump_matrix dq-
    (A = K G J), the impulse torque J^T iota = torque_matrix dq- (P = J^T G J), the impulse
    iota = impulse_map J dq- (G) and, with held contacts, the centre-of-mass velocity jump
    com_map iota (C = Jcom P_f J^T, 3 x 3; None for a fixed base, whose terms have no Jcom)."""

    jump_matrix: np.ndarray
    torque_matrix: np.ndarray
    impulse_map: np.ndarray
    com_map: np.ndarray | None


class JumpModel:
    """Common interface of the predictors: ``maps`` gives G, K (and W) of a state, once;
    ``matrices`` gives A and P.

    ``maps``, ``matrices``, ``jump_matrix`` and ``predict`` check their inputs (the normal is
    normalised, the restitution must lie in [0, 1]; ``validation.py``) and call ``unit_maps``
    or ``unit_matrices``, which take a unit normal and a valid restitution. A caller that has
    checked both once (``constraints.ExpectedImpact``) calls ``unit_matrices`` every cycle.
    Every method serves both forms (module docstring): ``unit_maps`` calls ``fixed_base_maps``
    without held contacts and ``held_maps`` with them."""

    name: str = ""

    def unit_maps(self, terms: ModelTerms, normal: np.ndarray, restitution: float) -> JumpMaps:
        if terms.held_jacobian.shape[0] == 0:
            return self.fixed_base_maps(terms, normal, restitution)
        self._check_held_contact_form()
        return self.held_maps(terms, normal, restitution)

    def fixed_base_maps(self, terms: ModelTerms, normal: np.ndarray, restitution: float) -> JumpMaps:
        raise NotImplementedError

    def held_maps(self, terms: ModelTerms, normal: np.ndarray, restitution: float) -> JumpMaps:
        raise NotImplementedError

    def _check_held_contact_form(self) -> None:
        if self.name not in HELD_CONTACT_METHODS:
            raise BadInputError(
                f"the {self.name} model has no held-contact form; choose from {', '.join(HELD_CONTACT_METHODS)}"
            )

    def unit_matrices(self, terms, normal: np.ndarray, restitution: float) -> JumpMatrices:
        """A, P, G (and C) of this state: the held-contact form (``jump_kernels.held_contact_maps``,
        from the terms' M_inv, J6, held_jacobian and Jcom) when the terms have held contacts,
        the fixed-base form (``fixed_base_matrices``) otherwise."""
        if terms.held_jacobian.shape[0] == 0:
            return self.fixed_base_matrices(terms, normal, restitution)
        self._check_held_contact_form()
        rigid = (terms.contact_point, terms.com, terms.inertia_com, terms.mass)
        method = HELD_CONTACT_METHODS.index(self.name)
        return JumpMatrices(
            *held_contact_maps(terms.M_inv, terms.J6, terms.held_jacobian, terms.Jcom, rigid, method, normal, restitution)
        )

    def fixed_base_matrices(self, terms: ModelTerms, normal: np.ndarray, restitution: float) -> JumpMatrices:
        """A = K G J and P = J^T G J from G and K (no held contact)."""
        maps = self.unit_maps(terms, normal, restitution)
        GJ = maps.G @ terms.J
        return JumpMatrices(maps.K @ GJ, terms.J.T @ GJ, maps.G, None)

    def maps(self, terms: ModelTerms, normal: np.ndarray, restitution: float) -> JumpMaps:
        """G, K (and W) for the surface normal ``normal`` and the restitution c_r."""
        return self.unit_maps(terms, unit_normal(normal), validation.restitution(restitution))

    def matrices(self, terms, normal: np.ndarray, restitution: float) -> JumpMatrices:
        """A and P (nv x nv), G (and C) for the surface normal ``normal`` and the restitution c_r."""
        return self.unit_matrices(terms, unit_normal(normal), validation.restitution(restitution))

    def jump_matrix(self, terms, normal: np.ndarray, restitution: float) -> np.ndarray:
        """A = K G J (nv x nv): the jump ddq = A dq- for a pre-impact joint velocity dq-."""
        return self.matrices(terms, normal, restitution).jump_matrix

    def predict(
        self,
        terms: ModelTerms,
        normal: np.ndarray,
        pre_impact_velocity: np.ndarray,
        restitution: float = 0.0,
        impulse: np.ndarray | None = None,
    ) -> JumpPrediction:
        """Predict the jump for the contact velocity v- (world), or from a measured impulse
        (then v- is not read). The normal n is normalised here. With held contacts the answer
        also holds their impulse lambda and the centre of mass's jump Jcom dv."""
        maps = self.maps(terms, normal, restitution)
        if impulse is None:
            impulse = maps.G @ validation.finite_vector(pre_impact_velocity, 3, "the pre-impact contact velocity")
        else:
            impulse = finite_vector(impulse, 3, "the impulse")
        dq_jump = maps.K @ impulse
        if terms.held_jacobian.shape[0] == 0:
            return JumpPrediction(self.name, dq_jump, impulse, maps.W)
        return JumpPrediction(
            self.name, dq_jump, impulse, maps.W, held_impulse(terms, impulse), terms.Jcom @ dq_jump
        )


class ClassicalJump(JumpModel):
    """Classical prediction, eqs. (5)-(6): iota_c = W_gm^-1 dv, ddq_c = M^-1 J^T iota_c,
    with the full 3-D dv = -(1+c_r) v-. It satisfies J ddq_c = dv."""

    name = "classical"

    def fixed_base_maps(self, terms, normal, restitution):
        MinvJt = joint_space_inverse_inertia_times_Jt(terms)
        return JumpMaps(-(1.0 + restitution) * np.linalg.inv(terms.J @ MinvJt), MinvJt, None)

    def held_maps(self, terms, normal, restitution):
        """G = -(1+c_r) W_gm^-1, K = P_f J^T."""
        return JumpMaps(
            -(1.0 + restitution) * np.linalg.inv(gm_inverse_inertia(terms)), joint_space_inverse_inertia_times_Jt(terms), None
        )

    def fixed_base_matrices(self, terms, normal, restitution):
        """A = M^-1 J^T G J, P = J^T G J and G in one compiled call (``classical_jump_matrices``)."""
        n = terms.J.shape[1]
        matrices = JumpMatrices(np.empty((n, n)), np.empty((n, n)), np.empty((3, 3)), None)
        classical_jump_matrices(terms.M_inv, terms.J, restitution, *matrices[:3])
        return matrices


class ClassicalNormalJump(ClassicalJump):
    """Classical prediction keeping only the normal part n n^T iota_c of the impulse (5),
    as in the paper's experiments (Sec. VI)."""

    name = "classical_normal"

    def fixed_base_maps(self, terms, normal, restitution):
        classical = super().fixed_base_maps(terms, normal, restitution)
        return JumpMaps(np.outer(normal, normal) @ classical.G, classical.K, None)

    fixed_base_matrices = JumpModel.fixed_base_matrices  # A = K G J from its own G


class GeneralizedMomentumJump(JumpModel):
    """Generalized-momentum prediction, eqs. (12), (22)-(23): W = W_gm = J M^-1 J^T,
    iota_n = -(1+c_r) n.v- / (n^T W n), ddq_gm = J+ W iota."""

    name = "gm"

    def inverse_inertia(self, terms: ModelTerms) -> np.ndarray:
        return gm_inverse_inertia(terms)

    def inverse_inertia_times(self, terms: ModelTerms, normal: np.ndarray) -> np.ndarray:
        """W n, the only product of W that the normal-impulse model (12) needs along n:
        J M^-1 (J^T n)."""
        return terms.J @ (terms.M_inv @ (normal @ terms.J))

    def fixed_base_maps(self, terms, normal, restitution):
        W = self.inverse_inertia(terms)
        return JumpMaps(normal_impulse_map(W, normal, restitution), terms.J_pinv @ W, W)

    def held_maps(self, terms, normal, restitution):
        """G = -(1+c_r) n n^T / (n^T W n), K = J# W."""
        W = self.inverse_inertia(terms)
        return JumpMaps(normal_impulse_map(W, normal, restitution), held_pinv(terms) @ W, W)

    def fixed_base_matrices(self, terms, normal, restitution):
        """A, P and G as the rank-one products of the module docstring, from W n alone
        (``inverse_inertia_times``, J+ = J^T (J J^T)^-1); compiled (``rank_one_jump_matrices``)."""
        n = terms.J.shape[1]
        matrices = JumpMatrices(np.empty((n, n)), np.empty((n, n)), np.empty((3, 3)), None)
        rank_one_jump_matrices(
            terms.J, terms.JJt_inv, self.inverse_inertia_times(terms, normal), normal, restitution, *matrices[:3]
        )
        return matrices


class CompositeRigidBodyJump(GeneralizedMomentumJump):
    """Composite-rigid-body prediction, eqs. (12), (20)-(21): W = W_crb,
    iota_n = -(1+c_r) n.v- / (n^T W_crb n), ddq_crb = J+ W_crb iota. No M involved."""

    name = "crb"

    def inverse_inertia(self, terms: ModelTerms) -> np.ndarray:
        return crb_inverse_inertia(terms)

    def fixed_base_maps(self, terms, normal, restitution):
        """G, K = J+ W_crb and W_crb in one compiled call (``crb_maps``)."""
        G, K, W = crb_maps(
            terms.contact_point, terms.com, terms.inertia_com, terms.mass, terms.J, terms.JJt_inv, normal, restitution
        )
        return JumpMaps(G, K, W)

    def predict(self, terms, normal, pre_impact_velocity, restitution=0.0, impulse=None) -> JumpPrediction:
        """``JumpModel.predict``; without held contacts and for a predicted impulse, W_crb (20),
        the impulse (12) and the jump (21) in one compiled call (``crb_jump``)."""
        if impulse is not None or terms.held_jacobian.shape[0]:
            return super().predict(terms, normal, pre_impact_velocity, restitution, impulse)
        normal, restitution = unit_normal(normal), validation.restitution(restitution)
        velocity = finite_vector(pre_impact_velocity, 3, "the pre-impact contact velocity")
        rigid = (terms.contact_point, terms.com, terms.inertia_com, terms.mass)
        outputs = np.empty(terms.J.shape[1]), np.empty(3), np.empty((3, 3))
        crb_jump(rigid, terms.J, terms.JJt_inv, (normal, velocity, restitution), outputs)
        return JumpPrediction(self.name, *outputs)

    def inverse_inertia_times(self, terms: ModelTerms, normal: np.ndarray) -> np.ndarray:
        """W_crb n = n / m - r x (I_c^-1 (r x n)), eq. (20) applied to n
        (([r]x)^T = -[r]x, so -[r]x I_c^-1 [r]x n is the expression above); compiled."""
        return crb_inverse_inertia_times(terms.contact_point, terms.com, terms.inertia_com, terms.mass, normal)


JUMP_MODELS: dict[str, JumpModel] = {
    m.name: m
    for m in (ClassicalJump(), ClassicalNormalJump(), GeneralizedMomentumJump(), CompositeRigidBodyJump())
}


def jump_model(name: str) -> JumpModel:
    try:
        return JUMP_MODELS[name]
    except KeyError:
        raise BadInputError(f"unknown jump model {name!r}; choose from {', '.join(JUMP_MODELS)}") from None


def predict(terms: ModelTerms, method: str, normal, pre_impact_velocity, restitution: float = 0.0) -> JumpPrediction:
    """The prediction of the method ``method`` (a name of ``JUMP_MODELS``) for the contact
    velocity v- (``JumpModel.predict``)."""
    return jump_model(method).predict(terms, normal, pre_impact_velocity, restitution)


def jump_from_impulse(terms: ModelTerms, impulse) -> np.ndarray:
    """dv = P_f J^T iota: the momentum law (held contacts kept still), fed a given (e.g.
    measured) impulse."""
    return joint_space_inverse_inertia_times_Jt(terms) @ finite_vector(impulse, 3, "the impulse")
