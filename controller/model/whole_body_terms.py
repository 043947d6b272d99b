"""Model terms of one state of the standing G1 for its whole-body QP (docs/whole-body-qp.md).

The state is (q, v): q the nq coordinates (base position, base quaternion, joints) and v the
nv velocities (base twist in the base frame, joint rates), Pinocchio's free-flyer convention.
The QP's unknown is the acceleration dv (nv, "ddq" in the tasks and constraints). Every frame
quantity is world-aligned (Pinocchio's LOCAL_WORLD_ALIGNED): for a frame with twist
[v_p; w] = J6 v, its time derivative is J6 dv + dJ6 v, where dJ6 v is the frame's classical
acceleration at dv = 0. The same holds for the centre of mass, dc = Jcom v and
ddc = Jcom dv + dJcom v.

``WholeBodyTerms`` carries the names the arm's tasks read (``q``, ``dq`` = v, ``J``, ``J6``,
``dJ6_dq``, ``contact_point``, ``contact_rotation``; the contact is the right hand's), the feet
(``Jf``, ``dJf_dq``: left then right, linear then angular rows), the centre of mass and the
torso frame (``frame("torso")``) and M^-1 (Pinocchio's ``computeMinverse``), what the
predictors' linear maps (``jump``, held-contact form) need, so that one cycle computes the model once.
A controller refills one WholeBodyTerms per cycle (``update_terms``); ``stamp`` changes at
every fill, so anything cached per state keys on it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit

from .floating_base import FloatingBaseModel
from .validation import BadInputError

TORSO_FRAME = "torso_link"
BASE_ACCELERATION_LIMIT = 100.0  # m/s^2 and rad/s^2: a generous box on the base (the feet set it)

_FILLS = itertools.count(1)


class FrameState(NamedTuple):
    """A frame's world position, rotation, world-aligned Jacobian (6 x nv) and drift dJ6 v."""

    position: np.ndarray
    rotation: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray


@dataclass(eq=False)
class WholeBodyTerms:
    """Every model quantity of one state (q, v) of the standing G1 (module docstring)."""

    q: np.ndarray
    dq: np.ndarray
    M: np.ndarray
    M_inv: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray
    contact_point: np.ndarray
    contact_rotation: np.ndarray
    Jf: np.ndarray
    dJf_dq: np.ndarray
    Jcom: np.ndarray
    dJcom_dq: np.ndarray
    com: np.ndarray
    mass: float
    inertia_com: np.ndarray
    frames: dict[str, FrameState]
    stamp: int = field(init=False, repr=False)

    def __post_init__(self):
        self.stamp = next(_FILLS)

    @property
    def J(self) -> np.ndarray:
        """The 3 x nv linear Jacobian of the contact point."""
        return self.J6[:3]

    @property
    def held_jacobian(self) -> np.ndarray:
        """The held contacts' Jacobian (the feet's ``Jf``), read by the held-contact jump maps
        (``controller.model.jump``) and rows (``constraints.HeldContactRows``)."""
        return self.Jf

    @property
    def held_drift(self) -> np.ndarray:
        """The held contacts' drift dJf/dt v (the feet's ``dJf_dq``)."""
        return self.dJf_dq

    def frame(self, name: str) -> FrameState:
        return self.frames[name]


class WholeBodyModel:
    """The G1 of ``FloatingBaseModel`` with the limits of its whole-body QP: the ``joints`` actuated
    joints' position, velocity, torque, acceleration and jerk limits from its description (the
    first three are the URDF's, the acceleration and jerk limits chosen in docs/whole-body-qp.md),
    and a box on the base's acceleration."""

    def __init__(self, base: FloatingBaseModel | None = None):
        self.base = base if base is not None else FloatingBaseModel()
        self.description = self.base.description
        self.model = self.base.model
        self.data = self.model.createData()
        self.nq, self.nv = self.model.nq, self.model.nv
        self.base_nq, self.base_nv = self.base.base_nq, self.base.base_nv
        self.joints = self.n_joints = self.base.n_joints
        self.q_min, self.q_max = self.base.q_min, self.base.q_max
        self.dq_max, self.tau_max = self.base.dq_max, self.base.tau_max
        self.ddq_max = self.base.description.ddq_max.copy()
        self.dddq_max = self.base.description.dddq_max.copy()
        self.torso_frame_id = self.model.getFrameId(TORSO_FRAME)
        self._zero = np.zeros(self.nv)

    def check_state(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) as float arrays; BadInputError unless they have nq and nv finite entries."""
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        if q.shape != (self.nq,) or v.shape != (self.nv,) or not (np.isfinite(q).all() and np.isfinite(v).all()):
            raise BadInputError(f"the state must be {self.nq} finite coordinates and {self.nv} finite velocities")
        return q, v

    def terms(self, q, v=None, *, check_limits: bool = False) -> WholeBodyTerms:
        """The terms of the state (q, v) (v = 0 when None), in new arrays (``check_limits``: the
        arm's signature; the joint limits are the QP's rows here)."""
        q, v = self.check_state(q, np.zeros(self.nv) if v is None else v)
        return self._fill(self.empty_terms(), q, v)

    def empty_terms(self) -> WholeBodyTerms:
        """A WholeBodyTerms of unset arrays, for ``update_terms`` to fill."""
        nv = self.nv
        frame = FrameState(np.empty(3), np.empty((3, 3)), np.empty((6, nv)), np.empty(6))
        return WholeBodyTerms(
            np.empty(self.nq), np.empty(nv), np.empty((nv, nv)), np.empty((nv, nv)), np.empty((6, nv)), np.empty(6),
            np.empty(3), np.empty((3, 3)), np.empty((12, nv)), np.empty(12), np.empty((3, nv)), np.empty(3),
            np.empty(3), 0.0, np.empty((3, 3)), {"torso": frame},
        )

    def update_terms(self, terms: WholeBodyTerms, q, v) -> WholeBodyTerms:
        """``terms(q, v)`` written into an existing WholeBodyTerms (a controller's per-cycle
        buffer: no new arrays), with a new ``stamp``; a refused state leaves it as it was."""
        q, v = self.check_state(q, v)
        return self._fill(terms, q, v)

    def _fill(self, terms: WholeBodyTerms, q: np.ndarray, v: np.ndarray) -> WholeBodyTerms:
        """One pass of Pinocchio's algorithms at (q, v), their results copied into ``terms``."""
        model, data = self.model, self.data
        terms.q[:], terms.dq[:] = q, v
        pin.forwardKinematics(model, data, q, v, self._zero)
        pin.computeJointJacobians(model, data)
        pin.updateFramePlacements(model, data)
        contact_id, (left, right) = self.base.contact_frame_id, self.base.foot_frame_ids
        self._frame_into(contact_id, terms.J6, terms.dJ6_dq, terms.contact_point, terms.contact_rotation)
        self._frame_into(left, terms.Jf[:6], terms.dJf_dq[:6])
        self._frame_into(right, terms.Jf[6:], terms.dJf_dq[6:])
        torso = terms.frames["torso"]
        self._frame_into(self.torso_frame_id, torso.J6, torso.dJ6_dq, torso.position, torso.rotation)
        pin.centerOfMass(model, data, pin.ACCELERATION, True)  # of the kinematics above
        terms.com[:], terms.dJcom_dq[:] = data.com[0], data.acom[0]
        terms.Jcom[:] = pin.jacobianCenterOfMass(model, data, False)  # of the Jacobians and CoMs above
        mirror_upper(pin.crba(model, data, q), terms.M)
        mirror_upper(pin.computeMinverse(model, data, q), terms.M_inv)
        pin.ccrba(model, data, q, v)
        terms.mass, terms.inertia_com[:] = float(data.Ig.mass), data.Ig.inertia
        terms.stamp = next(_FILLS)
        return terms

    def _frame_into(self, frame_id: int, J6, drift, position=None, rotation=None) -> None:
        """The frame's world-aligned Jacobian and drift (and its placement) after the forward
        kinematics of ``_fill``, copied into the given arrays."""
        world = pin.LOCAL_WORLD_ALIGNED
        J6[:] = pin.getFrameJacobian(self.model, self.data, frame_id, world)
        drift[:] = pin.getFrameClassicalAcceleration(self.model, self.data, frame_id, world).vector
        if position is not None:
            placement = self.data.oMf[frame_id]
            position[:], rotation[:] = placement.translation, placement.rotation


@njit(cache=True)
def mirror_upper(upper, out):
    """Kernel: out = the symmetric matrix whose upper triangle is ``upper``'s (Pinocchio fills
    only the upper triangles of M and M^-1)."""
    n = upper.shape[0]
    for i in range(n):
        for j in range(i, n):
            out[i, j] = upper[i, j]
            out[j, i] = upper[i, j]
