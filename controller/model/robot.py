"""Robot model: a described arm (``controller.model.robot_description``) in Pinocchio, fingers
locked, carrying a described tool (``controller.model.tool_description``).

The model is the single source of truth for the project: the MuJoCo scene of ``sim/`` is built
from the same URDF text (``robot_description.model_urdf``). All dynamic terms of one state are
computed once, by one call to ``pinocchio.computeAllTerms``, and gathered in :class:`ModelTerms`.

Contact tool
------------
The contact frame :data:`CONTACT_FRAME` (``impact_tip``) sits at the tool's contact point, with the
orientation of the frame the tool is fixed to. The tool's mass, centre of mass and inertia are
appended to the link that carries that frame, so M, the locked inertia and the CRB terms (20)
include them; a tool that replaces the Franka Hand removes the hand's inertia first.

The default, ``PandaModel()``, is the Panda with the ``impact_tip`` tool: a massless rigid sphere
of radius :data:`TOOL_RADIUS` whose centre sits on the hand's z axis (the axis of the fingers) at
:data:`TOOL_CENTRE_OFFSET` from the ``panda_hand`` frame, touching at its far pole
(:data:`TOOL_TIP_OFFSET`); a real tool's mass on it is a payload (``sim`` plant override
``payload_mass``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from numba import njit

from .robot_description import PANDA, RobotDescription, model_urdf, robot_description
from .tool_description import TOOLS, ToolDescription, tool_description
from .validation import BadInputError, all_finite

CONTACT_FRAME = "impact_tip"
TOOL_BODY = "tool"
"""The body (Pinocchio frame, MuJoCo body) of a tool with a mass, at its centre of mass."""
# The default robot and tool (``PandaModel()``): the Panda's hand frame and fingers, and the
# impact_tip sphere's radius, centre and contact point along the hand's axis.
HAND_FRAME = PANDA.hand_frame
FINGER_JOINTS = PANDA.finger_joints
TOOL_RADIUS = TOOLS["impact_tip"].geometry.radius
TOOL_CENTRE_OFFSET = float(TOOLS["impact_tip"].geometry.centre[2])
TOOL_TIP_OFFSET = float(TOOLS["impact_tip"].contact_point[2])
# The contact Jacobian counts as singular when sigma_min / sigma_max falls below this ratio.
SINGULAR_RATIO = 1e-3

MAX_STATE_ENTRY = 1e100
"""Largest |q_i| (rad) or |dq_i| (rad/s) of a joint state: far above any robot's, far enough
below the float range that the model's products of entries (kinetic energy, Coriolis terms)
cannot overflow."""
# The Panda's datasheet limits (robot_description.PANDA, docs/robots.md).
VELOCITY_LIMIT = PANDA.dq_max
TORQUE_LIMIT = PANDA.tau_max
ACCELERATION_LIMIT = PANDA.ddq_max
JERK_LIMIT = PANDA.dddq_max


class InvalidStateError(BadInputError):
    """A joint state that cannot be used: wrong shape, not finite, or outside the limits.

    ``constraint`` names what the state breaks: ``"finite_state"`` (shape or non-finite value)
    or ``"joint_position_limit"``.
    """

    def __init__(self, message: str, constraint: str = "finite_state"):
        super().__init__(message)
        self.constraint = constraint


class SingularPostureError(BadInputError):
    """The contact Jacobian is (numerically) rank deficient at this posture."""


_FILLS = itertools.count(1)


@dataclass(eq=False)
class ModelTerms:
    """Every model quantity of one joint state, computed once (``PandaModel.terms``).

    Attributes are world-aligned: ``J`` is the 3 x nv linear Jacobian of the contact point p,
    ``J6`` the 6 x nv (linear; angular) Jacobian of the contact frame, ``M`` the joint-space inertia
    matrix, ``h`` the bias forces (Coriolis, centrifugal, gravity), ``com`` the centre of mass of
    the moving links, ``mass`` their total mass and ``inertia_com`` the rotational inertia of the
    locked robot about ``com`` (world axes), used by the composite-rigid-body model (20).
    ``JJt_inv`` is (J J^T)^-1, so that the right inverse of (17) is J+ = J^T (J J^T)^-1.
    ``held_jacobian`` (0 x nv) and ``held_drift`` (0) are the held contacts' Jacobian Jf and drift
    dJf dq: a fixed-base arm holds none, the case of the held-contact jump maps with Jf empty
    (``controller.model.jump``).

    A controller refills one ModelTerms per cycle (``PandaModel.update_terms``); ``stamp``
    changes at every fill (and for a ``dataclasses.replace`` copy), so anything cached per
    state keys on it. The derived quantities below are computed on first use, once per fill.
    """

    q: np.ndarray
    dq: np.ndarray
    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    J6: np.ndarray
    dJ6_dq: np.ndarray  # dJ6/dt dq: contact-frame acceleration at ddq = 0
    JJt_inv: np.ndarray
    contact_point: np.ndarray
    contact_rotation: np.ndarray
    com: np.ndarray
    mass: float
    inertia_com: np.ndarray
    stamp: int = field(init=False, repr=False)
    held_jacobian: np.ndarray = field(init=False, repr=False)
    held_drift: np.ndarray = field(init=False, repr=False)
    _derived: dict = field(init=False, repr=False)

    def __post_init__(self):
        self.stamp = next(_FILLS)
        self.held_jacobian, self.held_drift = np.empty((0, self.J.shape[-1])), np.empty(0)
        self._derived = {}

    @property
    def J_pinv(self) -> np.ndarray:
        """J+ = J^T (J J^T)^-1, the right inverse of J used in (17)."""
        if "J_pinv" not in self._derived:
            self._derived["J_pinv"] = self.J.T @ self.JJt_inv
        return self._derived["J_pinv"]

    @property
    def M_cholesky(self):
        """Cholesky factor of M (scipy ``cho_factor``): M is never inverted explicitly."""
        if "M_cholesky" not in self._derived:
            from scipy.linalg import cho_factor

            self._derived["M_cholesky"] = cho_factor(self.M)
        return self._derived["M_cholesky"]

    @property
    def cond_M(self) -> float:
        if "cond_M" not in self._derived:
            self._derived["cond_M"] = float(np.linalg.cond(self.M))
        return self._derived["cond_M"]


def symmetric_inverse3(S: np.ndarray) -> tuple[list[list[float]], float]:
    """The inverse of a symmetric 3x3 matrix by its adjugate, in plain floats (no LAPACK call,
    which costs more than the arithmetic at this size), and its determinant."""
    (a, b, c), (_, d, e), (_, _, f) = S.tolist()
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    inv = 1.0 / det
    D, E, F = (a * f - c * c) * inv, (b * c - a * e) * inv, (a * d - b * b) * inv
    A, B, C = A * inv, B * inv, C * inv
    return [[A, B, C], [B, D, E], [C, E, F]], det


@njit(cache=True)
def symmetric_inverse3_into(S, out):
    """Compiled ``symmetric_inverse3`` (for kernels): the inverse of the symmetric 3x3 ``S`` by
    its adjugate into ``out`` (zeros when S is singular); returns det S."""
    a, b, c, d, e, f = S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    inv = 1.0 / det if det != 0.0 else 0.0
    D, E, F = (a * f - c * c) * inv, (b * c - a * e) * inv, (a * d - b * b) * inv
    A, B, C = A * inv, B * inv, C * inv
    out[0, 0], out[0, 1], out[0, 2] = A, B, C
    out[1, 0], out[1, 1], out[1, 2] = B, D, E
    out[2, 0], out[2, 1], out[2, 2] = C, E, F
    return det


class RobotModel:
    """A described arm (fingers locked) carrying a described contact tool.

    ``robot`` is a name of ``robot_description.ROBOTS`` or a ``RobotDescription``; ``tool`` a
    built-in tool name, a JSON/TOML tool file or a ``ToolDescription``.

    ``nq`` and ``nv`` are the model's numbers of coordinates and velocities (one per joint of the
    description). ``tool_frame_id`` is the frame the tool is fixed to (the hand or the flange),
    ``contact_frame_id`` the contact frame, ``hand_frame_id`` the hand's frame.

    >>> robot = RobotModel("fr3", "franka_hand")
    >>> terms = robot.terms(q, dq)
    """

    def __init__(
        self,
        robot: str | RobotDescription = "panda",
        tool: str | Path | ToolDescription = "impact_tip",
        *,
        urdf_path: str | Path | None = None,
        finger_opening: float = 0.0,
        base_placement: pin.SE3 | None = None,
    ):
        """Load the robot's URDF (or ``urdf_path``), lock the fingers at ``finger_opening`` (m),
        append the tool's inertia to its link and add the contact frame at its contact point.

        ``base_placement`` places the robot's base (link0) in the world; identity by default.
        """
        self.description = robot_description(robot)
        if self.description.floating:
            raise BadInputError(
                f"the {self.description.name} has a floating base: its model is FloatingBaseModel, not RobotModel"
            )
        self.tool = tool_description(tool)
        self.urdf_path = Path(urdf_path) if urdf_path is not None else self.description.urdf_path()
        model = self._arm(finger_opening)
        if base_placement is not None:
            model.jointPlacements[1] = base_placement * model.jointPlacements[1]
        names = tuple(model.names[i] for i in range(1, model.njoints))
        if names != self.description.joints or model.nq != model.nv:
            raise BadInputError(
                f"the {self.description.name} URDF's moving joints {', '.join(names)} are not the description's "
                f"joints {', '.join(self.description.joints)} (each a revolute or prismatic joint)"
            )
        masses = np.array([model.inertias[i].mass for i in range(1, model.njoints)])
        if not np.all(masses > 0.0):
            raise RuntimeError(f"the {self.description.name} model has links without mass: {masses}")
        mount = model.getFrameId(self.description.frame_of(self.tool))
        mount_frame = model.frames[mount]
        if self.tool.mass > 0.0:
            model.appendBodyToJoint(mount_frame.parentJoint, self.tool.spatial_inertia, mount_frame.placement)
            model.addFrame(pin.Frame(
                TOOL_BODY, mount_frame.parentJoint, mount,
                mount_frame.placement * pin.SE3(np.eye(3), self.tool.com.copy()), pin.FrameType.BODY,
            ))
        tip = pin.Frame(
            CONTACT_FRAME,
            mount_frame.parentJoint,
            mount,
            mount_frame.placement * pin.SE3(np.eye(3), self.tool.contact_point.copy()),
            pin.FrameType.OP_FRAME,
        )
        self.contact_frame_id = model.addFrame(tip)
        self.hand_frame_id = model.getFrameId(self.description.hand_frame) if self.description.hand_frame else None
        self.tool_frame_id = mount
        self.q_min = self.description.q_min.copy()
        self.q_max = self.description.q_max.copy()
        model.lowerPositionLimit, model.upperPositionLimit = self.q_min.copy(), self.q_max.copy()
        self.model = model
        self.data = model.createData()
        self.nq, self.nv = model.nq, model.nv
        self.base_nq = self.base_nv = 0  # a fixed base: every coordinate and velocity is a joint's
        self.n_joints = self.nv
        self.dq_max = self.description.dq_max.copy()
        self.tau_max = self.description.tau_max.copy()
        self.ddq_max = self.description.ddq_max.copy()
        self.dddq_max = self.description.dddq_max.copy()
        self._zero_velocity = np.zeros(self.nv)
        self._zero_velocity.flags.writeable = False

    def _arm(self, finger_opening: float) -> pin.Model:
        """The arm of ``model_urdf`` (hand removed when the tool replaces it), fingers locked."""
        full = pin.buildModelFromXML(model_urdf(self.description, self.tool, self.urdf_path))
        q_full = pin.neutral(full)
        locked = []
        for name in self.description.finger_joints:
            if full.existJointName(name):
                jid = full.getJointId(name)
                q_full[full.joints[jid].idx_q] = finger_opening
                locked.append(jid)
        return pin.buildReducedModel(full, locked, q_full)

    # ------------------------------------------------------------------ validation
    def check_state(self, q, dq=None, *, check_limits: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Return (q, dq) as float arrays, or raise :class:`InvalidStateError`."""
        q = np.asarray(q, dtype=float)
        dq = self._zero_velocity if dq is None else np.asarray(dq, dtype=float)
        if q.shape != (self.nq,) or dq.shape != (self.nv,):
            name, size, shape = ("q", self.nq, q.shape) if q.shape != (self.nq,) else ("dq", self.nv, dq.shape)
            raise InvalidStateError(f"{name} must have {size} values, got shape {shape}")
        # One sum of |entries| in plain floats (it cannot overflow into a warning, as a dot
        # product of large entries would) exceeds the bound when any entry is NaN, infinite or
        # too large; the precise test only runs then, to name the culprit.
        if not sum(map(abs, q.tolist())) + sum(map(abs, dq.tolist())) <= (self.nq + self.nv) * MAX_STATE_ENTRY:
            for name, values in (("q", q), ("dq", dq)):
                if not all_finite(values):
                    raise InvalidStateError(f"{name} contains a non-finite value")
            for name, values in (("q", q), ("dq", dq)):
                i = int(np.argmax(np.abs(values)))
                if abs(values[i]) > MAX_STATE_ENTRY:
                    raise InvalidStateError(
                        f"the state is too large to be a joint state: {name}{i + 1} = {values[i]:g}"
                    )
        if check_limits:
            outside = (q < self.q_min) | (q > self.q_max)
            if outside.any():
                i = int(np.flatnonzero(outside)[0])
                raise InvalidStateError(
                    f"q{i + 1} = {q[i]:.4f} rad is outside the joint limits "
                    f"[{self.q_min[i]:.4f}, {self.q_max[i]:.4f}]",
                    constraint="joint_position_limit",
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
        return self._fill(None, q, dq, check_limits)

    def update_terms(self, terms: ModelTerms, q, dq, *, check_limits: bool = True) -> ModelTerms:
        """``terms(q, dq)`` written into an existing ModelTerms (a controller's per-cycle
        buffer: no new object), with a new ``stamp``. Raises like ``terms``."""
        q, dq = self.check_state(q, dq, check_limits=False)
        return self._fill(terms, q, dq, check_limits)

    def _fill(self, terms: ModelTerms | None, q: np.ndarray, dq: np.ndarray, check_limits: bool) -> ModelTerms:
        model, data, fid = self.model, self.data, self.contact_frame_id
        pin.computeAllTerms(model, data, q, dq)
        pin.updateFramePlacement(model, data, fid)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        J = J6[:3]
        JJt_inv = np.empty((3, 3))
        status = contact_jacobian_status(J, q, self.q_min, self.q_max, check_limits, SINGULAR_RATIO**2, JJt_inv)
        if status == _NEAR_SINGULAR:
            eigenvalues = np.linalg.eigvalsh(J @ J.T)
            if not eigenvalues[0] >= (SINGULAR_RATIO**2) * eigenvalues[2]:
                raise SingularPostureError(
                    "singular contact Jacobian at this posture (singular values ratio "
                    f"{np.sqrt(max(eigenvalues[0], 0.0) / eigenvalues[2]):.1e})"
                )
        if status == _OUTSIDE_LIMITS or (status == _NEAR_SINGULAR and check_limits):
            self.check_state(q, dq, check_limits=True)  # raises, naming the joint, when outside
        # dJ6/dt dq (world-aligned) is the frame's classical acceleration at ddq = 0, which
        # computeAllTerms leaves in the data.
        dJ6_dq = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).vector.copy()
        placement = data.oMf[fid]
        centroidal = data.Ig
        fields = (
            q, dq, data.M.copy(), data.nle.copy(), J, J6, dJ6_dq, JJt_inv,
            placement.translation.copy(), placement.rotation.copy(), data.com[0].copy(),
            float(centroidal.mass), centroidal.inertia.copy(),
        )  # computeAllTerms fills both triangles of M
        if terms is None:
            return ModelTerms(*fields)
        (terms.q, terms.dq, terms.M, terms.h, terms.J, terms.J6, terms.dJ6_dq, terms.JJt_inv,
         terms.contact_point, terms.contact_rotation, terms.com, terms.mass, terms.inertia_com) = fields
        terms.stamp = next(_FILLS)
        terms._derived.clear()
        return terms

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


PandaModel = RobotModel
"""The historical name: ``PandaModel()`` is the default robot (the Panda) with the default tool."""


_ACCEPTED, _NEAR_SINGULAR, _OUTSIDE_LIMITS = 0, 1, 2


@njit(cache=True)
def contact_jacobian_status(J, q, q_min, q_max, check_limits, singular_ratio_squared, JJt_inv):
    """Kernel of the per-state checks: (J J^T)^-1 by its adjugate into ``JJt_inv``, then
    _NEAR_SINGULAR when det(J J^T) < ratio^2 trace^3 (with eigenvalues l1 <= l2 <= l3 of J J^T,
    the squared singular values of J, l1 / l3 >= det / trace^3: only then is the exact test
    needed), else _OUTSIDE_LIMITS when ``check_limits`` and q leaves [q_min, q_max], else
    _ACCEPTED."""
    S = J @ J.T
    det = symmetric_inverse3_into(S, JJt_inv)
    trace = S[0, 0] + S[1, 1] + S[2, 2]
    if not det >= singular_ratio_squared * trace * trace * trace:
        return _NEAR_SINGULAR
    if check_limits:
        for j in range(q.shape[0]):
            if q[j] < q_min[j] or q[j] > q_max[j]:
                return _OUTSIDE_LIMITS
    return _ACCEPTED
