"""Robot model: any described robot (``controller.model.robot_description``) in Pinocchio.

A fixed base (an arm) has its fingers locked and carries a described tool
(``controller.model.tool_description``); a floating base (a humanoid) has a free-flyer root
(its ``base_nq`` coordinates and ``base_nv`` velocities come before the joints'), its own
contact point (the description's ``contact``) and the contacts it holds (``held_contacts``:
a humanoid's soles). A fixed base is the case ``base_nq = base_nv = 0`` with no held contact.

The model is the single source of truth for the project: the MuJoCo scene of ``sim/`` is built
from the same URDF text (``robot_description.model_urdf``). All dynamic terms of one state are
gathered in :class:`~controller.model.model_terms.ModelTerms`, filled by the methods of
:class:`~controller.model.term_fills.ModelTermFills`: an arm's, for a controller's cycle, by one
call to ``pinocchio.computeAllTerms``, for a prediction from q (``terms``) by one world-frame
CRBA pass (the contact Jacobian and the locked robot's inertia; M, h and the drift on first
read); its centre-of-mass Jacobian, M^-1 and named frames only when asked; a floating base's in
one pass of the algorithms its whole-body QP needs.

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

import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

# SINGULAR_RATIO and SingularPostureError are the model's: their home is the fills that check them
from .term_fills import SINGULAR_RATIO, ModelTermFills, SingularPostureError  # noqa: F401
from .floating_kernels import QUATERNION_TOLERANCE
from .model_terms import MAX_STATE_ENTRY
from .files import read_text
from .robot_description import PANDA, RobotDescription, check_link_inertias, model_urdf, robot_description
from .tool_description import TOOLS, ToolDescription, tool_description
from .validation import BadInputError, all_finite, number_in_range, real_array

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

# The Panda's datasheet limits (robot_description.PANDA, docs/robots.md).
VELOCITY_LIMIT = PANDA.dq_max
TORQUE_LIMIT = PANDA.tau_max
ACCELERATION_LIMIT = PANDA.ddq_max
JERK_LIMIT = PANDA.dddq_max
BASE_ACCELERATION_LIMIT = 100.0
"""m/s^2 and rad/s^2: a generous box on a floating base's acceleration (the held contacts set it)."""
HELD_RANK_RATIO = 1e-8
"""The held contacts' stacked Jacobian has full rank while sigma_min / sigma_max stays above this
ratio: a numerical rank, far below any conditioning a real posture gives."""


class InvalidStateError(BadInputError):
    """A joint state that cannot be used: wrong shape, not finite, or outside the limits.

    ``constraint`` names what the state breaks: ``"finite_state"`` (shape or non-finite value)
    or ``"joint_position_limit"``.
    """

    def __init__(self, message: str, constraint: str = "finite_state"):
        super().__init__(message)
        self.constraint = constraint


class RobotModel(ModelTermFills):
    """A described robot: an arm (fingers locked) carrying a described contact tool, or a
    floating-base robot with its own contact point and its held contacts (module docstring).

    ``robot`` is a name of ``robot_description.ROBOTS``, a robot file or a ``RobotDescription``;
    ``tool`` a built-in tool name, a JSON/TOML tool file or a ``ToolDescription`` (a fixed base
    only; ``impact_tip`` by default).

    ``nq`` and ``nv`` are the model's numbers of coordinates and velocities: the base's
    ``base_nq`` and ``base_nv`` (0 for a fixed base) then one per joint of the description
    (``n_joints`` = nv - base_nv). The joint limits ``q_min``, ``q_max``, ``dq_max``,
    ``tau_max``, ``ddq_max``, ``dddq_max`` are the description's, over the actuated joints.
    ``contact_frame_id`` is the contact frame, ``held_frames`` and ``held_frame_ids`` the held
    contacts' frames in the description's order, ``frame_ids`` the description's named
    frames; an arm's ``tool_frame_id`` is the frame the tool is fixed to (the hand or the
    flange), ``hand_frame_id`` the hand's frame. The terms of a state (``terms``,
    ``update_terms``, ``empty_terms``, ``body_terms``, ``inverse_inertia``) are the fills of
    :class:`~controller.model.term_fills.ModelTermFills`.

    >>> robot = RobotModel("fr3", "franka_hand")
    >>> terms = robot.terms(q, dq)
    """

    def __init__(
        self,
        robot: str | Path | RobotDescription = "panda",
        tool: str | Path | ToolDescription | None = None,
        *,
        urdf_path: str | Path | None = None,
        finger_opening: float = 0.0,
        base_placement: pin.SE3 | None = None,
    ):
        """Load the robot's URDF (or ``urdf_path``); for a fixed base, lock the fingers at
        ``finger_opening`` (m), append the tool's inertia to its link and add the contact frame
        at its contact point; for a floating base, add a free-flyer root and the description's
        contact frame.

        ``base_placement`` places a fixed base (link0) in the world; identity by default.
        """
        self.description = description = robot_description(robot)
        self.urdf_path = Path(urdf_path) if urdf_path is not None else description.urdf_path()
        if description.floating:
            if tool is not None or base_placement is not None:
                raise BadInputError(f"the floating-base {description.name} carries no tool and stands where its feet are")
            self.tool = None
            model = self._floating_base()
        else:
            self.tool = tool_description("impact_tip" if tool is None else tool)
            model = self._fixed_base(finger_opening, base_placement)
        self.model = model
        self.data = model.createData()
        self.nq, self.nv = model.nq, model.nv
        root = model.joints[1]  # a floating base's free flyer
        self.base_nq, self.base_nv = (root.nq, root.nv) if description.floating else (0, 0)
        self.n_joints = model.nv - self.base_nv
        first = 2 if description.floating else 1
        self.joint_names = [model.names[i] for i in range(first, model.njoints)]
        if tuple(self.joint_names) != description.joints or model.nq - self.base_nq != self.n_joints:
            raise BadInputError(
                f"the {description.name} URDF's moving joints {', '.join(self.joint_names)} are not the "
                f"description's joints {', '.join(description.joints)} (each a revolute or prismatic joint)"
            )
        self.held_frames = tuple(c.frame for c in description.held_contacts)
        missing = [f for f in (*self.held_frames, *description.frames.values()) if not model.existFrame(f)]
        if missing:
            raise BadInputError(f"the {description.name} URDF has no frame {', '.join(missing)}")
        self.held_frame_ids = tuple(model.getFrameId(name) for name in self.held_frames)
        check_held_contacts_independent(model, self.held_frame_ids, description)
        if description.floating:
            check_contact_joints_move_the_contact(model, self.contact_frame_id, description)
        self.frame_ids = {name: model.getFrameId(frame) for name, frame in description.frames.items()}
        self.q_min = description.q_min.copy()
        self.q_max = description.q_max.copy()
        self.dq_max = description.dq_max.copy()
        self.tau_max = description.tau_max.copy()
        self.ddq_max = description.ddq_max.copy()
        self.dddq_max = description.dddq_max.copy()
        self._zero_velocity = np.zeros(self.nv)
        self._zero_velocity.flags.writeable = False
        check_inertia_matrix(model, description)
        self._prepare_fills()

    @property
    def floating(self) -> bool:
        """Whether the base is floating (a free-flyer root before the joints)."""
        return self.base_nv > 0

    def _fixed_base(self, finger_opening: float, base_placement: pin.SE3 | None) -> pin.Model:
        """The arm with its tool's inertia and contact frame (module docstring)."""
        model = self._arm(finger_opening)
        if base_placement is not None:
            model.jointPlacements[1] = base_placement * model.jointPlacements[1]
        masses = np.array([model.inertias[i].mass for i in range(1, model.njoints)])
        if not np.all(masses > 0.0):
            moving = [model.names[i] for i in range(1, model.njoints) if not masses[i - 1] > 0.0]
            what = f"the joint {moving[0]} moves" if len(moving) == 1 else f"the joints {', '.join(moving)} move"
            raise BadInputError(f"the {self.description.name} URDF gives no positive mass to what {what}")
        mount_name = self.description.frame_of(self.tool)
        if not model.existFrame(mount_name):
            raise BadInputError(f"the {self.description.name} URDF has no frame {mount_name} (its tool frame)")
        mount = model.getFrameId(mount_name)
        if model.frames[mount].parentJoint == 0:
            raise BadInputError(f"the {self.description.name} tool frame {mount_name} is on the fixed base: no joint moves it")
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
        self.contact_frame_name = CONTACT_FRAME
        self.contact_frame_id = model.addFrame(tip)
        self.hand_frame_id = model.getFrameId(self.description.hand_frame) if self.description.hand_frame else None
        self.tool_frame_id = mount
        model.lowerPositionLimit, model.upperPositionLimit = self.description.q_min.copy(), self.description.q_max.copy()
        return model

    def _arm(self, finger_opening: float) -> pin.Model:
        """The arm of ``model_urdf`` (hand removed when the tool replaces it), fingers locked."""
        full = parsed_urdf(self.description.name, pin.buildModelFromXML, model_urdf(self.description, self.tool, self.urdf_path))
        q_full = pin.neutral(full)
        locked = []
        for name in self.description.finger_joints:
            if full.existJointName(name):
                jid = full.getJointId(name)
                i = full.joints[jid].idx_q
                number_in_range(finger_opening, full.lowerPositionLimit[i], full.upperPositionLimit[i], "the finger opening", "m")
                q_full[i] = finger_opening
                locked.append(jid)
        return pin.buildReducedModel(full, locked, q_full)

    def _floating_base(self) -> pin.Model:
        """The URDF under a free-flyer root, with the description's contact frame."""
        description = self.description
        if description.contact is None or not description.held_contacts:
            raise BadInputError(f"the floating-base {description.name} needs a contact and held contacts in its description")
        check_link_inertias(read_text(self.urdf_path, f"the {description.name} URDF"), description.name)
        model = parsed_urdf(description.name, pin.buildModelFromUrdf, str(self.urdf_path), pin.JointModelFreeFlyer())
        contact = description.contact
        if not model.existFrame(contact.frame):
            raise BadInputError(f"the {description.name} URDF has no frame {contact.frame}")
        parent = model.getFrameId(contact.frame)
        frame = model.frames[parent]
        offset = pin.SE3(np.eye(3), contact.offset.copy())
        self.contact_frame_name = contact.name
        self.contact_frame_id = model.addFrame(
            pin.Frame(contact.name, frame.parentJoint, parent, frame.placement * offset, pin.FrameType.OP_FRAME)
        )
        self.hand_frame_id, self.tool_frame_id = None, parent
        return model

    def joint_index(self, name: str) -> int:
        """Index of a joint in the joint part of q (0 .. n_joints - 1)."""
        return self.joint_names.index(name)

    # ------------------------------------------------------------------ validation
    def check_state(self, q, dq=None, *, check_limits: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Return (q, dq) as float arrays (dq = 0 when None), or raise :class:`InvalidStateError`:
        wrong sizes, a non-finite or huge entry, a floating base's quaternion that is not a unit
        one, or (``check_limits``) an actuated joint outside its position limits (a floating
        base's coordinates are not limited)."""
        q = real_array(q, "q", InvalidStateError)
        dq = self._zero_velocity if dq is None else real_array(dq, "dq", InvalidStateError)
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
        if self.base_nq:  # a free flyer's orientation is a unit quaternion (x, y, z, w)
            norm = math.sqrt(sum(x * x for x in q[3:self.base_nq].tolist()))
            if abs(norm - 1.0) > QUATERNION_TOLERANCE:
                raise InvalidStateError(f"the base orientation q4..q7 must be a unit quaternion, its norm is {norm:.6g}")
        if check_limits:
            joints = q[self.base_nq:]
            outside = (joints < self.q_min) | (joints > self.q_max)
            if outside.any():
                i = int(np.flatnonzero(outside)[0])
                raise InvalidStateError(
                    f"{self.joint_names[i]} = {joints[i]:.4f} is outside its limits "
                    f"[{self.q_min[i]:.4f}, {self.q_max[i]:.4f}]" if self.base_nq else
                    f"q{i + 1} = {joints[i]:.4f} rad is outside the joint limits "
                    f"[{self.q_min[i]:.4f}, {self.q_max[i]:.4f}]",
                    constraint="joint_position_limit",
                )
        return q, dq

    # ------------------------------------------------------------------ frames
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

    def frame_placements(self, q) -> dict[str, pin.SE3]:
        """World placements of the contact frame and the held contacts' frames; InvalidStateError
        for a q that is not a state (``check_state``; the limits are not checked)."""
        q, _ = self.check_state(q, check_limits=False)
        pin.framesForwardKinematics(self.model, self.data, q)
        ids = {self.contact_frame_name: self.contact_frame_id, **dict(zip(self.held_frames, self.held_frame_ids))}
        return {name: self.data.oMf[i].copy() for name, i in ids.items()}

    def sole_corners(self, q) -> np.ndarray:
        """World positions (k x 3) of the sole corners of every held contact, in the description's
        order (the G1: 4 corners of the left foot, then 4 of the right), each corner (x, y) of the
        contact's ``sole`` at its ``depth`` below the contact's frame; none for a fixed base."""
        placements = self.frame_placements(q)
        return np.vstack([np.empty((0, 3))] + [
            [placements[c.frame].act(p) for p in np.column_stack([c.sole, np.full(len(c.sole), -c.depth)])]
            for c in self.description.held_contacts
        ])


PandaModel = RobotModel
"""The historical name: ``PandaModel()`` is the default robot (the Panda) with the default tool."""


def generic_posture(model: pin.Model, description: RobotDescription) -> np.ndarray:
    """A posture without special alignment: the joints drawn uniformly inside their limits (within
    +-pi where a limit is infinite) by a fixed generator, the base at its origin."""
    q = pin.neutral(model)
    low = np.where(np.isfinite(description.q_min), description.q_min, -math.pi)
    high = np.where(np.isfinite(description.q_max), description.q_max, math.pi)
    q[model.nq - len(low):] = np.random.default_rng(0).uniform(low, high)
    return q


def check_inertia_matrix(model: pin.Model, description: RobotDescription) -> None:
    """BadInputError when the joint-space inertia M at a generic posture (``generic_posture``) is
    not finite, or not positive definite: a joint axis of zero length (which Pinocchio normalises
    into NaN), or a joint that moves no inertia. Every predictor and the QP need M^-1."""
    M = pin.crba(model, model.createData(), generic_posture(model, description))
    M = np.triu(M) + np.triu(M, 1).T
    try:
        if not all_finite(M.ravel()):
            raise np.linalg.LinAlgError
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise BadInputError(
            f"the {description.name} URDF gives a joint-space inertia that is not finite and positive definite "
            "(a joint axis of zero length, or a joint that moves no inertia?)"
        ) from None


def check_contact_joints_move_the_contact(model: pin.Model, frame_id: int, description: RobotDescription) -> None:
    """BadInputError when a standing robot's contact joints (``contact.joints``: the arm its
    approach moves while the held contacts stay) cannot move its contact point in every
    direction at a generic posture (``generic_posture``): no approach along a wall's normal."""
    names = description.contact.joints if description.contact.joints else description.joints
    data = model.createData()
    pin.computeJointJacobians(model, data, generic_posture(model, description))
    pin.updateFramePlacements(model, data)
    J = pin.getFrameJacobian(model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    columns = [model.joints[model.getJointId(name)].idx_v for name in names]
    singular_values = np.linalg.svd(J[:, columns], compute_uv=False)
    if len(columns) < 3 or singular_values[2] <= HELD_RANK_RATIO * singular_values[0]:
        raise BadInputError(
            f"the {description.name} contact joints ({', '.join(names)}) cannot move its contact point "
            f"{description.contact.frame} in every direction"
        )


def check_held_contacts_independent(model: pin.Model, frame_ids: tuple[int, ...], description: RobotDescription) -> None:
    """BadInputError when the held contacts cannot be held independently: their stacked 6-D
    Jacobian Jf (6 k x nv) is rank deficient at a generic posture (``generic_posture``), so
    Jf M^-1 Jf^T, which every held-contact jump map (eq. 22-23) and the whole-body QP invert, is
    singular at every state: two held contacts on one rigid body, more held rows than velocities,
    or a held contact whose frame no velocity moves in some direction. A rank lost only at
    particular postures is not this check's."""
    if not frame_ids:
        return
    data = model.createData()
    pin.computeJointJacobians(model, data, generic_posture(model, description))
    pin.updateFramePlacements(model, data)
    Jf = np.vstack([pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in frame_ids])
    singular_values = np.linalg.svd(Jf, compute_uv=False)
    if len(singular_values) < Jf.shape[0] or singular_values[-1] <= HELD_RANK_RATIO * singular_values[0]:
        rank = int(np.sum(singular_values > HELD_RANK_RATIO * singular_values[0]))
        names = ", ".join(contact.name for contact in description.held_contacts)
        raise BadInputError(
            f"the {description.name} held contacts ({names}) cannot be held independently: their stacked "
            f"Jacobian has rank {rank} of {Jf.shape[0]} (two on one rigid body?)"
        )


def parsed_urdf(robot: str, build, *args) -> pin.Model:
    """``build(*args)`` (Pinocchio's URDF parser), BadInputError when it refuses the URDF: its
    first message (urdfdom's, which the C++ parser writes on the process's stderr, caught here so
    that a refused file stays one line) or its error's."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        try:
            return build(*args)
        except (RuntimeError, ValueError) as error:
            reason = str(error)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        lines = [line.strip() for line in captured.read().decode(errors="replace").splitlines() if line.strip()]
    reason = next((line for line in lines if line.lower().startswith("error")), reason).removeprefix("Error:").strip()
    raise BadInputError(f"the {robot} URDF is not a robot model Pinocchio reads: {reason}")
