"""Floating-base humanoid (Unitree G1) and its hand-impact jump predictors (docs/floating-base.md).

The model is built from a floating-base robot description (``robot_description``, docs/robots.md;
the built-in ``g1``): its URDF with a free-flyer root (its ``base_nq`` coordinates and ``base_nv``
velocities come before the joints'), the robot's own contact point (the description's
``contact``: a frame at an offset from a URDF frame) and the contacts it holds
(``held_contacts``: the feet, each a URDF frame with its sole polygon and depth). The G1 is the
29-joint G1 of ``example-robot-data``: its URDF has no fingers, gripper or head joints, so
nothing needs to be locked. Its contact point p sits on the right forearm axis (the x axis of
``right_wrist_yaw_link``), 10 cm beyond the wrist, inside the rubber hand; its feet are the two
``*_ankle_roll_link`` bodies, their soles 35 mm below those frames.

Impact model (Wang, Dehio, Kheddar, RA-L 2022, extended to a floating base standing on two
feet). The generalized velocity v = (base twist in the base frame, joint rates) jumps by dv
under a hand impulse iota and the feet's impulses lambda (a wrench per foot, world axes at the
foot frame):

    M dv = J^T iota + Jf^T lambda,    Jf dv = 0                       (feet stay in contact)

so dv = P J^T iota with the constrained inverse inertia
P = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 and lambda = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T iota.
The contact-point inverse inertia of the standing robot is W_gm = J P J^T (22).

- classical (5)-(6): iota = W_gm^-1 dv_c with dv_c = -(1 + c_r) v-, jump P J^T iota.
- gm (12), (22)-(23): normal impulse iota = iota_n n with W_gm, jump J# W_gm iota.
- crb (12), (20)-(21): normal impulse with W_crb = (1/m) I3 - [r]x I_c^-1 [r]x of the whole
  robot locked into one free rigid body (mass m, centroidal inertia I_c from CCRBA,
  r = p - c), jump J# W_crb iota.

J# is the least-norm right inverse of J among the motions that keep the feet still:
J# = N (J N)^+ with N the orthogonal projector onto the null space of Jf.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.linalg import cho_factor, cho_solve

from .jump import crb_inverse_inertia
from .robot_description import RobotDescription, robot_description
from .validation import BadInputError, unit_normal

METHODS = ("classical", "gm", "crb")


@dataclass(eq=False)
class FloatingBaseTerms:
    """Model quantities of one configuration q (nq values), world-aligned.

    ``J`` is the 3 x nv linear Jacobian of the contact point, ``Jf`` the Jacobian of the held
    contacts' frames (6 rows each, in the description's order: 12 x nv for the G1's left then
    right foot; linear then angular rows), ``Jcom`` the 3 x nv Jacobian of the centre of mass,
    ``M`` the joint-space inertia matrix (base and joints), ``com``, ``mass`` and ``inertia_com``
    the centre of mass, total mass and centroidal rotational inertia (world axes) of the whole
    robot locked into one rigid body.
    """

    q: np.ndarray
    M: np.ndarray
    J: np.ndarray
    Jf: np.ndarray
    Jcom: np.ndarray
    contact_point: np.ndarray
    com: np.ndarray
    mass: float
    inertia_com: np.ndarray
    _derived: dict = field(default_factory=dict, repr=False)

    def _cached(self, key, build):
        if key not in self._derived:
            self._derived[key] = build()
        return self._derived[key]

    @property
    def M_inv_Jf_t(self) -> np.ndarray:
        """M^-1 Jf^T by a Cholesky solve."""
        return self._cached("MiJf", lambda: cho_solve(self._cho(), self.Jf.T))

    def _cho(self):
        return self._cached("cho", lambda: cho_factor(self.M))

    def constrained_inverse_inertia(self) -> np.ndarray:
        """P = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1: dv = P tau_impulse with the feet held."""

        def build():
            MiJf = self.M_inv_Jf_t
            Mi = cho_solve(self._cho(), np.eye(self.M.shape[0]))
            P = Mi - MiJf @ np.linalg.solve(self.Jf @ MiJf, MiJf.T)
            return 0.5 * (P + P.T)

        return self._cached("P", build)

    def feet_impulse(self, impulse: np.ndarray) -> np.ndarray:
        """lambda = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T iota: the feet's wrenches (12) that keep them still."""
        MiJf = self.M_inv_Jf_t
        return -np.linalg.solve(self.Jf @ MiJf, MiJf.T @ (self.J.T @ impulse))

    def feet_held_pinv(self) -> np.ndarray:
        """J# = N (J N)^+ (nv x 3), N the projector onto null(Jf): least-norm dv with J dv = x, Jf dv = 0."""

        def build():
            N = np.eye(self.M.shape[0]) - np.linalg.pinv(self.Jf) @ self.Jf
            return N @ np.linalg.pinv(self.J @ N)

        return self._cached("Jsharp", build)


@dataclass(frozen=True)
class FloatingJump:
    """A predicted impact: generalized-velocity jump ``dv`` (nv), hand impulse ``impulse`` (3),
    feet wrenches ``feet_impulse`` (12, what keeps the feet still under ``impulse``) and the
    centre-of-mass velocity jump ``com_jump`` = Jcom dv (3)."""

    dv: np.ndarray
    impulse: np.ndarray
    feet_impulse: np.ndarray
    com_jump: np.ndarray


def gm_inverse_inertia(terms: FloatingBaseTerms) -> np.ndarray:
    """W_gm = J P J^T (22), P the inverse inertia with both feet held (bilateral contacts)."""
    W = terms.J @ terms.constrained_inverse_inertia() @ terms.J.T
    return 0.5 * (W + W.T)


def normal_impulse(W: np.ndarray, n: np.ndarray, v_minus: np.ndarray, c_r: float) -> np.ndarray:
    """iota = iota_n n, iota_n = -(1 + c_r) (n.v-) / (n^T W n), eq. (12)."""
    return -(1.0 + c_r) * (n @ v_minus) / (n @ W @ n) * n


def predict(terms: FloatingBaseTerms, method: str, normal, v_minus, c_r: float = 0.0) -> FloatingJump:
    """The jump of the standing robot for a hand impact at pre-impact contact velocity v-.

    ``normal`` is the surface normal (pointing towards the robot), c_r the restitution.
    """
    n = unit_normal(normal)
    v_minus = np.asarray(v_minus, dtype=float)
    if v_minus.shape != (3,) or not np.all(np.isfinite(v_minus)):
        raise BadInputError("the pre-impact contact velocity must be 3 finite numbers")
    if not 0.0 <= c_r <= 1.0:
        raise BadInputError(f"the restitution must lie in [0, 1], got {c_r}")
    if method == "classical":
        W = gm_inverse_inertia(terms)
        impulse = np.linalg.solve(W, -(1.0 + c_r) * v_minus)  # (6)
        dv = terms.constrained_inverse_inertia() @ (terms.J.T @ impulse)
    elif method in ("gm", "crb"):
        W = gm_inverse_inertia(terms) if method == "gm" else crb_inverse_inertia(terms)
        impulse = normal_impulse(W, n, v_minus, c_r)
        dv = terms.feet_held_pinv() @ (W @ impulse)  # (21), (23)
    else:
        raise BadInputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    return FloatingJump(dv, impulse, terms.feet_impulse(impulse), terms.Jcom @ dv)


def jump_from_impulse(terms: FloatingBaseTerms, impulse: np.ndarray) -> np.ndarray:
    """dv = P J^T iota: the momentum law with the feet held, fed a given (e.g. measured) impulse."""
    return terms.constrained_inverse_inertia() @ (terms.J.T @ np.asarray(impulse, dtype=float))


class FloatingBaseModel:
    """A floating-base robot with a free-flyer root, its own contact point and its held contacts
    (the G1: the right hand's contact point and the two feet), built from its description.

    q and v start with the free flyer's ``base_nq`` coordinates (position, quaternion) and
    ``base_nv`` velocities (the base twist); the ``n_joints`` actuated joints follow.

    ``robot`` is a floating-base description, a built-in name or a robot file
    (``robot_description``); ``urdf_path`` replaces the description's URDF. The joint limits
    (``q_min``, ``q_max``, ``dq_max``, ``tau_max``) are the description's; ``foot_frames`` and
    ``foot_frame_ids`` are the held contacts' frames in the description's order.
    """

    def __init__(self, robot: str | Path | RobotDescription = "g1", urdf_path: str | Path | None = None):
        self.description = description = robot_description(robot)
        if not description.floating:
            raise BadInputError(f"the {description.name} has a fixed base: its model is RobotModel, not FloatingBaseModel")
        if description.contact is None or not description.held_contacts:
            raise BadInputError(f"the floating-base {description.name} needs a contact and held contacts in its description")
        self.urdf_path = Path(urdf_path) if urdf_path is not None else description.urdf_path()
        model = pin.buildModelFromUrdf(str(self.urdf_path), pin.JointModelFreeFlyer())
        self.foot_frames = tuple(c.frame for c in description.held_contacts)
        missing = [f for f in (description.contact.frame, *self.foot_frames) if not model.existFrame(f)]
        if missing:
            raise BadInputError(f"the {description.name} URDF has no frame {', '.join(missing)}")
        contact = description.contact
        hand = model.getFrameId(contact.frame)
        frame = model.frames[hand]
        offset = pin.SE3(np.eye(3), contact.offset.copy())
        self.contact_frame_name = contact.name
        self.contact_frame_id = model.addFrame(
            pin.Frame(contact.name, frame.parentJoint, hand, frame.placement * offset, pin.FrameType.OP_FRAME)
        )
        self.foot_frame_ids = tuple(model.getFrameId(name) for name in self.foot_frames)
        self.model = model
        self.data = model.createData()
        self.joint_names = [model.names[i] for i in range(2, model.njoints)]
        root = model.joints[1]  # the free flyer
        self.base_nq, self.base_nv = root.nq, root.nv
        self.n_joints = model.nv - self.base_nv
        if tuple(self.joint_names) != description.joints:
            raise BadInputError(
                f"the {description.name} URDF's moving joints {', '.join(self.joint_names)} are not the "
                f"description's joints {', '.join(description.joints)}"
            )
        self.q_min = description.q_min.copy()
        self.q_max = description.q_max.copy()
        self.dq_max = description.dq_max.copy()
        self.tau_max = description.tau_max.copy()

    def joint_index(self, name: str) -> int:
        """Index of a joint in the joint part of q (0 .. n_joints - 1)."""
        return self.joint_names.index(name)

    def terms(self, q) -> FloatingBaseTerms:
        """Every quantity of the predictors at the configuration q (nq values)."""
        model, data = self.model, self.data
        q = np.asarray(q, dtype=float)
        if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
            raise BadInputError(f"q must be {model.nq} finite numbers")
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        world = pin.LOCAL_WORLD_ALIGNED
        J = pin.getFrameJacobian(model, data, self.contact_frame_id, world)[:3].copy()
        Jf = np.vstack([pin.getFrameJacobian(model, data, f, world) for f in self.foot_frame_ids])
        Jcom = pin.jacobianCenterOfMass(model, data, q).copy()
        pin.ccrba(model, data, q, np.zeros(model.nv))
        Ig = data.Ig
        return FloatingBaseTerms(
            q.copy(), M, J, Jf, Jcom, data.oMf[self.contact_frame_id].translation.copy(),
            data.com[0].copy(), float(Ig.mass), Ig.inertia.copy(),
        )

    def frame_placements(self, q) -> dict[str, pin.SE3]:
        """World placements of the contact frame and the held contacts' frames."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        ids = {self.contact_frame_name: self.contact_frame_id, **dict(zip(self.foot_frames, self.foot_frame_ids))}
        return {name: self.data.oMf[i].copy() for name, i in ids.items()}

    def sole_corners(self, q) -> np.ndarray:
        """World positions (k x 3) of the sole corners of every held contact, in the description's
        order (the G1: 4 corners of the left foot, then 4 of the right), each corner (x, y) of the
        contact's ``sole`` at its ``depth`` below the contact's frame."""
        placements = self.frame_placements(q)
        return np.vstack([
            [placements[c.frame].act(p) for p in np.column_stack([c.sole, np.full(len(c.sole), -c.depth)])]
            for c in self.description.held_contacts
        ])
