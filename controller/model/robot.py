"""Panda model: the example-robot-data URDF in Pinocchio, fingers locked, with a contact tool.

The model is the single source of truth for the project: the MuJoCo scene of ``sim/`` is built
from the same URDF file. All dynamic terms of one state are computed once, by one call to
``pinocchio.computeAllTerms``, and gathered in :class:`ModelTerms`.

Contact tool
------------
A rigid sphere of radius :data:`TOOL_RADIUS` whose centre sits on the hand's z axis (the axis of
the fingers) at :data:`TOOL_CENTRE_OFFSET` from the ``panda_hand`` frame. The contact frame
:data:`CONTACT_FRAME` (``impact_tip``) is at the far pole of the sphere, on the same axis, with
the hand's orientation. The tool is massless: a real tool's mass is a payload (``sim`` plant
override ``payload_mass``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import pinocchio as pin

from .validation import BadInputError

NQ = 7
HAND_FRAME = "panda_hand"
CONTACT_FRAME = "impact_tip"
TOOL_RADIUS = 0.02
TOOL_CENTRE_OFFSET = 0.12
TOOL_TIP_OFFSET = TOOL_CENTRE_OFFSET + TOOL_RADIUS
# The contact Jacobian counts as singular when sigma_min / sigma_max falls below this ratio.
SINGULAR_RATIO = 1e-3
FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")

# Franka datasheet limits (docs/predictors.md, Conventions).
VELOCITY_LIMIT = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
TORQUE_LIMIT = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
ACCELERATION_LIMIT = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
JERK_LIMIT = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])


class InvalidStateError(BadInputError):
    """A joint state that cannot be used: wrong shape, not finite, or outside the limits."""


class SingularPostureError(BadInputError):
    """The contact Jacobian is (numerically) rank deficient at this posture."""


def panda_urdf_path() -> Path:
    """Path of the Panda URDF shipped by the ``example-robot-data`` package."""
    import example_robot_data

    subpath = "panda_description/urdf/panda.urdf"
    return (Path(example_robot_data.getModelPath(subpath)) / subpath).resolve()


@dataclass(frozen=True)
class ModelTerms:
    """Every model quantity of one joint state, computed once (``PandaModel.terms``).

    Attributes are world-aligned: ``J`` is the 3x7 linear Jacobian of the contact point p,
    ``J6`` the 6x7 (linear; angular) Jacobian of the contact frame, ``M`` the joint-space inertia
    matrix, ``h`` the bias forces (Coriolis, centrifugal, gravity), ``com`` the centre of mass of
    the moving links, ``mass`` their total mass and ``inertia_com`` the rotational inertia of the
    locked robot about ``com`` (world axes), used by the composite-rigid-body model (20).
    """

    q: np.ndarray
    dq: np.ndarray
    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray  # dJ6/dt dq: contact-frame acceleration at ddq = 0
    J_pinv: np.ndarray  # J+ = J^T (J J^T)^-1, the right inverse of J used in (17)
    contact_point: np.ndarray
    contact_rotation: np.ndarray
    com: np.ndarray
    mass: float
    inertia_com: np.ndarray

    @cached_property
    def M_cholesky(self):
        """Cholesky factor of M (scipy ``cho_factor``): M is never inverted explicitly."""
        from scipy.linalg import cho_factor

        return cho_factor(self.M)

    @cached_property
    def cond_M(self) -> float:
        return float(np.linalg.cond(self.M))


class PandaModel:
    """The 7-DoF Panda (fingers locked) with the spherical contact tool.

    >>> robot = PandaModel()
    >>> terms = robot.terms(q, dq)
    """

    def __init__(
        self,
        urdf_path: str | Path | None = None,
        finger_opening: float = 0.0,
        base_placement: pin.SE3 | None = None,
    ):
        """Load the URDF, lock the fingers at ``finger_opening`` (m) and add the contact tool.

        ``base_placement`` places the robot's base (link0) in the world; identity by default.
        """
        self.urdf_path = Path(urdf_path) if urdf_path is not None else panda_urdf_path()
        full = pin.buildModelFromUrdf(str(self.urdf_path))
        q_full = pin.neutral(full)
        locked = []
        for name in FINGER_JOINTS:
            jid = full.getJointId(name)
            q_full[full.joints[jid].idx_q] = finger_opening
            locked.append(jid)
        model = pin.buildReducedModel(full, locked, q_full)
        if base_placement is not None:
            model.jointPlacements[1] = base_placement * model.jointPlacements[1]
        if model.nq != NQ:
            raise RuntimeError(f"expected a 7-DoF Panda, got nq={model.nq}")
        masses = np.array([model.inertias[i].mass for i in range(1, model.njoints)])
        if not np.all(masses > 0.0):
            raise RuntimeError(f"the Panda model has links without mass: {masses}")
        hand = model.getFrameId(HAND_FRAME)
        hand_frame = model.frames[hand]
        tip = pin.Frame(
            CONTACT_FRAME,
            hand_frame.parentJoint,
            hand,
            hand_frame.placement * pin.SE3(np.eye(3), np.array([0.0, 0.0, TOOL_TIP_OFFSET])),
            pin.FrameType.OP_FRAME,
        )
        self.contact_frame_id = model.addFrame(tip)
        self.hand_frame_id = hand
        self.model = model
        self.data = model.createData()
        self.q_min = model.lowerPositionLimit.copy()
        self.q_max = model.upperPositionLimit.copy()
        self.dq_max = VELOCITY_LIMIT.copy()
        self.tau_max = TORQUE_LIMIT.copy()
        self.ddq_max = ACCELERATION_LIMIT.copy()
        self.dddq_max = JERK_LIMIT.copy()
        self._zero_velocity = np.zeros(NQ)
        self._zero_velocity.flags.writeable = False

    # ------------------------------------------------------------------ validation
    def check_state(self, q, dq=None, *, check_limits: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Return (q, dq) as float arrays, or raise :class:`InvalidStateError`."""
        q = np.asarray(q, dtype=float)
        dq = self._zero_velocity if dq is None else np.asarray(dq, dtype=float)
        if q.shape != (NQ,) or dq.shape != (NQ,):
            name, shape = ("q", q.shape) if q.shape != (NQ,) else ("dq", dq.shape)
            raise InvalidStateError(f"{name} must have {NQ} values, got shape {shape}")
        # One dot product is non-finite when any entry is (NaN or inf); the precise test only
        # runs then, to name the culprit.
        if not math.isfinite(q @ q + dq @ dq):
            for name, values in (("q", q), ("dq", dq)):
                if not np.all(np.isfinite(values)):
                    raise InvalidStateError(f"{name} contains a non-finite value")
            raise InvalidStateError("the state is too large to be a joint state")
        if check_limits:
            outside = (q < self.q_min) | (q > self.q_max)
            if outside.any():
                i = int(np.flatnonzero(outside)[0])
                raise InvalidStateError(
                    f"q{i + 1} = {q[i]:.4f} rad is outside the joint limits "
                    f"[{self.q_min[i]:.4f}, {self.q_max[i]:.4f}]"
                )
        return q, dq

    # ------------------------------------------------------------------ model terms
    def terms(self, q, dq=None, *, check_limits: bool = True) -> ModelTerms:
        """All model terms of the state (q, dq), from one ``computeAllTerms`` call.

        Raises :class:`SingularPostureError` when the contact Jacobian J is rank deficient
        (assumption 5 of the paper: sigma_min(J) < SINGULAR_RATIO sigma_max(J)), checked before
        the joint limits, and :class:`InvalidStateError` for a bad or out-of-limit state.
        """
        q, dq = self.check_state(q, dq, check_limits=False)
        model, data, fid = self.model, self.data, self.contact_frame_id
        pin.computeAllTerms(model, data, q, dq)
        pin.updateFramePlacement(model, data, fid)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        dJ6 = pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        J = J6[:3]
        eigenvalues, eigenvectors = np.linalg.eigh(J @ J.T)
        if eigenvalues[0] < (SINGULAR_RATIO**2) * eigenvalues[2]:
            raise SingularPostureError(
                "singular contact Jacobian at this posture (singular values ratio "
                f"{np.sqrt(max(eigenvalues[0], 0.0) / eigenvalues[2]):.1e})"
            )
        if check_limits and ((q < self.q_min) | (q > self.q_max)).any():
            self.check_state(q, dq, check_limits=True)
        placement = data.oMf[fid]
        return ModelTerms(
            q=q,
            dq=dq,
            M=data.M.copy(),  # computeAllTerms fills both triangles of M
            h=data.nle.copy(),
            J=J,
            J6=J6,
            dJ6_dq=dJ6 @ dq,
            J_pinv=J.T @ ((eigenvectors / eigenvalues) @ eigenvectors.T),
            contact_point=placement.translation.copy(),
            contact_rotation=placement.rotation.copy(),
            com=data.com[0].copy(),
            mass=float(data.Ig.mass),
            inertia_com=data.Ig.inertia.copy(),
        )

    def contact_point(self, q) -> np.ndarray:
        """World position of the contact point (forward kinematics only)."""
        q, _ = self.check_state(q, check_limits=False)
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.contact_frame_id].translation.copy()

    def contact_frame(self, q) -> pin.SE3:
        q, _ = self.check_state(q, check_limits=False)
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.contact_frame_id].copy()

    def contact_jacobian6(self, q) -> np.ndarray:
        q, _ = self.check_state(q, check_limits=False)
        return pin.computeFrameJacobian(
            self.model, self.data, q, self.contact_frame_id, pin.LOCAL_WORLD_ALIGNED
        )
