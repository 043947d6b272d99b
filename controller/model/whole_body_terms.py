"""Model terms of one state of the standing G1 for its whole-body QP (docs/whole-body-qp.md).

The state is (q, v): q the 36 coordinates (base position, base quaternion, 29 joints) and v the
35 velocities (base twist in the base frame, joint rates), Pinocchio's free-flyer convention.
The QP's unknown is the acceleration dv (35, "ddq" in the tasks and constraints). Every frame
quantity is world-aligned (Pinocchio's LOCAL_WORLD_ALIGNED): for a frame with twist
[v_p; w] = J6 v, its time derivative is J6 dv + dJ6 v, where dJ6 v is the frame's classical
acceleration at dv = 0. The same holds for the centre of mass, dc = Jcom v and
ddc = Jcom dv + dJcom v.

``WholeBodyTerms`` carries the names the arm's tasks read (``q``, ``dq`` = v, ``J``, ``J6``,
``dJ6_dq``, ``contact_point``, ``contact_rotation``; the contact is the right hand's), the feet
(``Jf``, ``dJf_dq``: left then right, linear then angular rows), the centre of mass and the
torso frame (``frame("torso")``) and M^-1 (Pinocchio's ``computeMinverse``), what the
predictors' linear maps (``floating_maps``) need, so that one cycle computes the model once.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .floating_base import NB, FloatingBaseModel
from .validation import BadInputError

TORSO_FRAME = "torso_link"
JOINT_ACCELERATION_LIMIT = 25.0  # rad/s^2, every actuated joint (docs/whole-body-qp.md, Limits)
JOINT_JERK_LIMIT = 10_000.0  # rad/s^3
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

    def frame(self, name: str) -> FrameState:
        return self.frames[name]


class WholeBodyModel:
    """The G1 of ``FloatingBaseModel`` with the limits of its whole-body QP: the 29 actuated
    joints' position, velocity and torque limits from the URDF, the acceleration and jerk
    limits chosen in docs/whole-body-qp.md, and a box on the base's acceleration."""

    def __init__(self, base: FloatingBaseModel | None = None):
        self.base = base if base is not None else FloatingBaseModel()
        self.model = self.base.model
        self.data = self.model.createData()
        self.nq, self.nv = self.model.nq, self.model.nv
        self.joints = self.nv - NB
        self.q_min, self.q_max = self.base.q_min, self.base.q_max
        self.dq_max, self.tau_max = self.base.dq_max, self.base.tau_max
        self.ddq_max = np.full(self.joints, JOINT_ACCELERATION_LIMIT)
        self.dddq_max = np.full(self.joints, JOINT_JERK_LIMIT)
        self.torso_frame_id = self.model.getFrameId(TORSO_FRAME)
        self._lower = np.tril_indices(self.nv, -1)  # Pinocchio fills the upper triangles of M, M^-1

    def check_state(self, q, v) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) as float arrays; BadInputError unless they have nq and nv finite entries."""
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        if q.shape != (self.nq,) or v.shape != (self.nv,) or not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise BadInputError(f"the state must be {self.nq} finite coordinates and {self.nv} finite velocities")
        return q, v

    def terms(self, q, v=None) -> WholeBodyTerms:
        """The terms of the state (q, v) (v = 0 when None), computed once."""
        q, v = self.check_state(q, np.zeros(self.nv) if v is None else v)
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, np.zeros(self.nv))
        pin.computeJointJacobians(model, data)
        pin.updateFramePlacements(model, data)
        contact = self._frame_state(self.base.contact_frame_id)
        feet = [self._frame_state(f) for f in self.base.foot_frame_ids]
        torso = self._frame_state(self.torso_frame_id)
        M = self._symmetric(pin.crba(model, data, q))
        M_inv = self._symmetric(pin.computeMinverse(model, data, q))
        pin.centerOfMass(model, data, q, v, np.zeros(self.nv))
        com, dJcom_dq = data.com[0].copy(), data.acom[0].copy()
        Jcom = pin.jacobianCenterOfMass(model, data, q).copy()
        pin.ccrba(model, data, q, v)
        Ig = data.Ig
        return WholeBodyTerms(
            q, v, M, M_inv, contact.J6, contact.dJ6_dq, contact.position, contact.rotation,
            np.vstack([f.J6 for f in feet]), np.concatenate([f.dJ6_dq for f in feet]),
            Jcom, dJcom_dq, com, float(Ig.mass), Ig.inertia.copy(),
            {"torso": torso},
        )

    def _symmetric(self, upper: np.ndarray) -> np.ndarray:
        """A copy of a matrix whose upper triangle is filled, mirrored into the lower one."""
        full = upper.copy()
        full[self._lower] = full.T[self._lower]
        return full

    def _frame_state(self, frame_id: int) -> FrameState:
        """The frame's ``FrameState`` after the forward kinematics of ``terms`` (world-aligned)."""
        model, data = self.model, self.data
        world = pin.LOCAL_WORLD_ALIGNED
        placement = data.oMf[frame_id]
        return FrameState(
            placement.translation.copy(), placement.rotation.copy(),
            pin.getFrameJacobian(model, data, frame_id, world),
            pin.getFrameClassicalAcceleration(model, data, frame_id, world).vector.copy(),
        )
