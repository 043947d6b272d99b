"""The composite-rigid-body prediction of a fixed-base arm from q alone, computing only what it
needs (docs/predictors.md, "The fast CRB path").

A prediction from q needs the locked robot's mass m, centre of mass c and rotational inertia
I_c about c (world axes), the contact point p and the contact point's world-aligned linear
Jacobian J: nothing of M, h or the drift. One compiled pass (``crb_state``) over the
kinematic tree does it from the tree's constants (:class:`KinematicTree`, read once from the
Pinocchio model):

- forward kinematics, oMi = oMi(parent) jointPlacement_i exp(q_i a_i) (a revolute joint turns
  about its axis a_i by Rodrigues' formula, a prismatic one slides along it);
- the locked inertia: m = sum m_i, c = sum m_i c_i / m, I_c = sum R_i I_i R_i^T +
  m_i (|c_i - c|^2 I3 - (c_i - c)(c_i - c)^T) (the subtree inertia of the root, Pinocchio's
  ``oYcrb``, which the CRB model (20) welds);
- J: for every joint k that carries the contact, z_k x (p - o_k) (revolute, z_k = R_k a_k) or
  z_k (prismatic); (J J^T)^-1 by the adjugate, with the singularity test of
  ``model_terms.contact_jacobian_status``;

then W_crb (20), the impulse (12) and the jump (21) (``jump_kernels.crb_jump``). No BLAS or
LAPACK call: a batch (``crb_batch``, one compiled loop over the states) runs on one thread
whatever the machine's BLAS does. A state the kernel does not accept (bad input, a
near-singular J, a joint outside its limits) goes through the general path
(``RobotModel.terms`` and ``CompositeRigidBodyJump.predict``), which raises the one-line error
or, for a J that its exact test clears, predicts.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import validation
from .jump import JUMP_MODELS, JumpPrediction
from .jump_kernels import crb_jump
from .model_terms import ACCEPTED, contact_jacobian_status
from .term_fills import SINGULAR_RATIO
from .validation import NORMAL_MIN_NORM

REVOLUTE, PRISMATIC = 0, 1
JOINT_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
"""The axes of Pinocchio's axis-aligned one-degree joints (JointModelRX ... JointModelPZ)."""
REJECTED = -1
"""``checked_crb_prediction``'s status of a bad input (q, the normal, the velocity or the restitution)."""
# columns of a KinematicTree's joint table
PARENT, KIND, AXIS, ROTATION, TRANSLATION, MASS, LEVER, INERTIA, ON_PATH = 0, 1, 2, 5, 14, 17, 18, 21, 30
COLUMNS = 31


def joint_kind(joint) -> tuple[int, tuple[float, float, float]]:
    """(REVOLUTE or PRISMATIC, unit axis in the joint frame) of a Pinocchio joint model, or
    ValueError for a joint the compiled pass does not model."""
    name = joint.shortname()
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        return (REVOLUTE if "Revolute" in name else PRISMATIC), tuple(float(a) for a in joint.axis)
    if len(name) == len("JointModelRZ") and name[-2] in "RP" and name[-1] in JOINT_AXES:
        return (REVOLUTE if name[-2] == "R" else PRISMATIC), JOINT_AXES[name[-1]]
    raise ValueError(f"the compiled CRB pass models one-degree revolute and prismatic joints, not {name}")


class KinematicTree:
    """The constants of a fixed-base robot's tree for ``crb_state``: one row per joint (parent,
    kind, axis, placement in the parent, link mass, centre of mass and inertia in the joint frame,
    whether it carries the contact), the contact's joint and placement, the position limits."""

    def __init__(self, robot):
        model = robot.model
        if robot.floating:
            raise ValueError("the compiled CRB pass is for fixed-base robots")
        frame = model.frames[robot.contact_frame_id]
        carriers, joint = set(), frame.parentJoint
        while joint > 0:
            carriers.add(joint)
            joint = model.parents[joint]
        table = np.zeros((model.njoints - 1, COLUMNS))
        for i in range(1, model.njoints):
            kind, axis = joint_kind(model.joints[i])
            placement, inertia = model.jointPlacements[i], model.inertias[i]
            row = table[i - 1]
            row[PARENT], row[KIND], row[AXIS:AXIS + 3] = model.parents[i] - 1, kind, axis
            row[ROTATION:ROTATION + 9] = placement.rotation.ravel()
            row[TRANSLATION:TRANSLATION + 3] = placement.translation
            row[MASS], row[LEVER:LEVER + 3] = inertia.mass, inertia.lever
            row[INERTIA:INERTIA + 9] = inertia.inertia.ravel()
            row[ON_PATH] = i in carriers
        self.joints = table
        self.contact_joint = frame.parentJoint - 1
        self.contact_translation = frame.placement.translation.copy()
        self.q_min, self.q_max = robot.q_min.copy(), robot.q_max.copy()


@njit(cache=True, inline="always")
def joint_rotation(kind, ax, ay, az, angle, out):
    """Kernel: the rotation of a joint at its coordinate into ``out``: about the unit axis a by
    Rodrigues' formula I + s [a]x + (1 - c) [a]x^2 for a revolute joint, I for a prismatic one."""
    s, c = (math.sin(angle), math.cos(angle)) if kind == REVOLUTE else (0.0, 1.0)
    t = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + t * ax * ax, t * ax * ay - s * az, t * ax * az + s * ay
    out[1, 0], out[1, 1], out[1, 2] = t * ax * ay + s * az, c + t * ay * ay, t * ay * az - s * ax
    out[2, 0], out[2, 1], out[2, 2] = t * ax * az - s * ay, t * ay * az + s * ax, c + t * az * az


@njit(cache=True, inline="always")
def crb_state(tree, q, state, work):
    """Kernel: forward kinematics of the tree (``tree`` = (``KinematicTree``'s joint table,
    contact joint, contact translation, ...)) at q; into ``state`` = (J, contact point, centre
    of mass, inertia about it) the contact point's world-aligned linear Jacobian (3 x nv) and the
    locked robot's centre of mass and inertia (module docstring); returns the locked robot's
    mass. ``work``: (each joint's world rotation and origin, its link's centre of mass, two 3 x 3
    products), overwritten. One coordinate per joint, in the order
    of the table."""
    joints, contact_joint, contact_translation = tree[0], tree[1], tree[2]
    J, point, com, inertia = state
    R, o, com_i, Rq, placed = work
    n = joints.shape[0]
    for i in range(n):
        parent = int(joints[i, PARENT])
        for a in range(3):  # (R_parent Rp, o_parent + R_parent tp), or (Rp, tp) at the root
            o[i, a] = joints[i, TRANSLATION + a]
            for b in range(3):
                placed[a, b] = joints[i, ROTATION + 3 * a + b]
            if parent >= 0:
                o[i, a] = o[parent, a]
                for k in range(3):
                    o[i, a] += R[parent, a, k] * joints[i, TRANSLATION + k]
                for b in range(3):
                    placed[a, b] = R[parent, a, 0] * joints[i, ROTATION + b] + R[parent, a, 1] * joints[i, ROTATION + 3 + b] \
                        + R[parent, a, 2] * joints[i, ROTATION + 6 + b]
        joint_rotation(joints[i, KIND], joints[i, AXIS], joints[i, AXIS + 1], joints[i, AXIS + 2], q[i], Rq)
        for a in range(3):
            for b in range(3):
                R[i, a, b] = placed[a, 0] * Rq[0, b] + placed[a, 1] * Rq[1, b] + placed[a, 2] * Rq[2, b]
        for a in range(3):
            if joints[i, KIND] == PRISMATIC:
                o[i, a] += q[i] * (R[i, a, 0] * joints[i, AXIS] + R[i, a, 1] * joints[i, AXIS + 1]
                                   + R[i, a, 2] * joints[i, AXIS + 2])
            com_i[i, a] = o[i, a] + R[i, a, 0] * joints[i, LEVER] + R[i, a, 1] * joints[i, LEVER + 1] \
                + R[i, a, 2] * joints[i, LEVER + 2]
    mass = 0.0
    com[:] = 0.0
    for i in range(n):
        mass += joints[i, MASS]
        for a in range(3):
            com[a] += joints[i, MASS] * com_i[i, a]
    for a in range(3):
        com[a] /= mass
    inertia[:, :] = 0.0
    for i in range(n):
        m_i = joints[i, MASS]
        d0, d1, d2 = com_i[i, 0] - com[0], com_i[i, 1] - com[1], com_i[i, 2] - com[2]
        squared = d0 * d0 + d1 * d1 + d2 * d2
        for a in range(3):  # R_i I_i, then (R_i I_i) R_i^T below
            for b in range(3):
                Rq[a, b] = R[i, a, 0] * joints[i, INERTIA + b] + R[i, a, 1] * joints[i, INERTIA + 3 + b] \
                    + R[i, a, 2] * joints[i, INERTIA + 6 + b]
        for a in range(3):
            da = com_i[i, a] - com[a]
            for b in range(3):
                db = com_i[i, b] - com[b]
                rotated = Rq[a, 0] * R[i, b, 0] + Rq[a, 1] * R[i, b, 1] + Rq[a, 2] * R[i, b, 2]
                inertia[a, b] += rotated + m_i * ((squared if a == b else 0.0) - da * db)
    for a in range(3):
        point[a] = o[contact_joint, a]
        for b in range(3):
            point[a] += R[contact_joint, a, b] * contact_translation[b]
    for i in range(n):
        if joints[i, ON_PATH] == 0.0:
            J[0, i], J[1, i], J[2, i] = 0.0, 0.0, 0.0
            continue
        ax, ay, az = joints[i, AXIS], joints[i, AXIS + 1], joints[i, AXIS + 2]
        z0 = R[i, 0, 0] * ax + R[i, 0, 1] * ay + R[i, 0, 2] * az
        z1 = R[i, 1, 0] * ax + R[i, 1, 1] * ay + R[i, 1, 2] * az
        z2 = R[i, 2, 0] * ax + R[i, 2, 1] * ay + R[i, 2, 2] * az
        if joints[i, KIND] == PRISMATIC:
            J[0, i], J[1, i], J[2, i] = z0, z1, z2
        else:
            r0, r1, r2 = point[0] - o[i, 0], point[1] - o[i, 1], point[2] - o[i, 2]
            J[0, i], J[1, i], J[2, i] = z1 * r2 - z2 * r1, z2 * r0 - z0 * r2, z0 * r1 - z1 * r0
    return mass


@njit(cache=True)
def unit_normal_into(normal, out):
    """Kernel: ``validation.unit_normal`` (n / |n|, the norm taken on n / max |n_i|) into ``out``;
    False for a non-finite or (near-)zero normal."""
    scale = max(abs(normal[0]), abs(normal[1]), abs(normal[2]))
    if not (np.isfinite(scale) and scale > 0.0):
        return False
    x, y, z = normal[0] / scale, normal[1] / scale, normal[2] / scale
    norm = math.sqrt(x * x + y * y + z * z)
    if scale * norm < NORMAL_MIN_NORM:
        return False
    out[0], out[1], out[2] = x / norm, y / norm, z / norm
    return True


@njit(cache=True)
def scratch(nv):
    """Kernel: the scratch arrays of ``crb_prediction`` for nv joints."""
    state = (np.empty((3, nv)), np.empty(3), np.empty(3), np.empty((3, 3)))
    work = (np.empty((nv, 3, 3)), np.empty((nv, 3)), np.empty((nv, 3)), np.empty((3, 3)), np.empty((3, 3)))
    return state, np.empty((3, 3)), work


@njit(cache=True, inline="always")
def crb_prediction(tree, q, impact, outputs, check_limits, buffers):
    """Kernel of one CRB prediction from q: ``crb_state`` at q, (J J^T)^-1 with the checks of
    ``contact_jacobian_status`` (its status when not ACCEPTED), then W_crb (20), the impulse
    (12) and the jump (21) (``crb_jump``) into ``outputs`` = (jump, impulse, W_crb).
    ``tree`` = (joint table, contact joint, contact translation, q_min, q_max, squared singular
    ratio), ``impact`` = (unit normal, pre-impact contact velocity, restitution), ``buffers`` =
    ``scratch``: ((J, contact point, centre of mass, inertia), (J J^T)^-1, ``crb_state``'s work),
    overwritten."""
    q_min, q_max, singular_ratio_squared = tree[3], tree[4], tree[5]
    state, JJt_inv, work = buffers
    mass = crb_state(tree, q, state, work)
    J, point, com, inertia = state
    status = contact_jacobian_status(J, q, q_min, q_max, check_limits, singular_ratio_squared, JJt_inv)
    if status != ACCEPTED:
        return status
    crb_jump((point, com, inertia, mass), J, JJt_inv, impact, outputs)
    return ACCEPTED


@njit(cache=True)
def checked_crb_prediction(tree, q, normal, velocity, restitution, outputs):
    """Kernel of ``CrbPredictor.predict``: REJECTED when q, n or v- is not finite, n is zero or
    c_r is outside [0, 1], else ``crb_prediction`` with n normalised and the joint limits
    checked."""
    unit = np.empty(3)
    if not (0.0 <= restitution <= 1.0) or not unit_normal_into(normal, unit):
        return REJECTED
    for value in velocity:
        if not np.isfinite(value):
            return REJECTED
    for value in q:
        if not np.isfinite(value):
            return REJECTED
    return crb_prediction(tree, q, (unit, velocity, restitution), outputs, True, scratch(tree[0].shape[0]))


def pack_tree(tree: tuple) -> np.ndarray:
    """``CrbPredictor``'s tree (joint table, contact joint, contact translation, q_min, q_max,
    squared singular ratio) in one flat array (``unpacked_tree``): [rows, nq, contact joint, squared
    ratio, contact translation, q_min, q_max, the joint table row by row]. numba types a tuple
    argument element by element at every call, an array at once."""
    joints, contact_joint, translation, q_min, q_max, ratio = tree
    head = [joints.shape[0], q_min.shape[0], contact_joint, ratio]
    return np.concatenate([head, translation, q_min, q_max, joints.ravel()]).astype(float)


@njit(cache=True)
def unpacked_tree(packed):
    """Kernel: the tree of ``pack_tree``'s array, as views of it."""
    rows, nq = int(packed[0]), int(packed[1])
    limits_end = 7 + 2 * nq
    joints = packed[limits_end:limits_end + rows * COLUMNS].reshape((rows, COLUMNS))
    return joints, int(packed[2]), packed[4:7], packed[7:7 + nq], packed[7 + nq:limits_end], packed[3]


@njit(cache=True)
def packed_crb_prediction(packed, q, normal, velocity, restitution, jump, impulse, W):
    """Kernel of ``CrbPredictor.predict``: ``checked_crb_prediction`` of the tree packed in one
    array (``pack_tree``) into jump, impulse and W."""
    return checked_crb_prediction(unpacked_tree(packed), q, normal, velocity, restitution, (jump, impulse, W))


@njit(cache=True)
def crb_batch(tree, Q, normals, velocities, restitution, outputs):
    """Kernel of ``CrbPredictor.predict_batch``: ``crb_prediction`` without the limit check
    (``tree`` with a squared singular ratio of -inf: no singularity check) for every row of Q (N x nv),
    unit normals and velocities (N x 3), into ``outputs`` = (jumps N x nv, impulses N x 3)."""
    jumps, impulses = outputs
    W, work = np.empty((3, 3)), scratch(Q.shape[1])
    for k in range(Q.shape[0]):
        crb_prediction(tree, Q[k], (normals[k], velocities[k], restitution), (jumps[k], impulses[k], W), False, work)


class CrbPredictor:
    """The CRB prediction of one fixed-base arm from q (module docstring): ``predict`` for one
    state, ``predict_batch`` for N."""

    def __init__(self, robot):
        self.robot = robot
        tree = KinematicTree(robot)
        self.tree = (tree.joints, tree.contact_joint, tree.contact_translation, tree.q_min, tree.q_max,
                     SINGULAR_RATIO**2)
        self.unchecked_tree = self.tree[:5] + (-np.inf,)  # every finite J accepted: the batch's
        self.packed_tree = pack_tree(self.tree)  # ``predict``'s, one argument
        self._q_shape = (robot.nq,)

    def predict(self, q, normal, pre_impact_velocity, restitution: float = 0.0) -> JumpPrediction:
        """``CompositeRigidBodyJump.predict(robot.terms(q), normal, pre_impact_velocity,
        restitution)``, the same numbers and the same bad input, from one compiled call."""
        arrays = np.asarray(q, dtype=float), np.asarray(normal, dtype=float), np.asarray(pre_impact_velocity, dtype=float)
        if arrays[0].shape == self._q_shape and arrays[1].shape == arrays[2].shape == (3,) and type(restitution) in (float, int, np.float64):
            jump, impulse, W = np.empty(self._q_shape), np.empty(3), np.empty((3, 3))
            if packed_crb_prediction(self.packed_tree, *arrays, float(restitution), jump, impulse, W) == ACCEPTED:
                return JumpPrediction("crb", jump, impulse, W)
        return JUMP_MODELS["crb"].predict(self.robot.terms(q), normal, pre_impact_velocity, restitution)

    def predict_batch(self, Q, normals, pre_impact_velocities, restitution: float = 0.0, out=None) -> tuple[np.ndarray, np.ndarray]:
        """Jumps (N, nv) and impulses (N, 3) of N states (``batch.predict_batch`` with "crb"):
        Q (N, nv), normals and velocities (N, 3) or (3,), one compiled loop (``crb_batch``),
        written into ``out`` = (jumps, impulses) when given (e.g. views of shared memory)."""
        Q = validation.state_rows(Q, self._q_shape[0], "Q")
        N = Q.shape[0]
        # Writable row-major copies where needed (a broadcast is read-only): one compiled signature.
        Q = np.require(Q, requirements="CW")
        normals = np.require(validation.vector_rows(validation.unit_normals(normals), N, "the surface normals"), requirements="CW")
        velocities = np.require(validation.vector_rows(pre_impact_velocities, N, "the pre-impact velocities"), requirements="CW")
        outputs = (np.empty((N, self._q_shape[0])), np.empty((N, 3))) if out is None else out
        for output in outputs:
            output[:] = np.nan  # the rows of a J with a non-finite entry stay NaN
        crb_batch(self.unchecked_tree, Q, normals, velocities, validation.restitution(restitution), outputs)
        return outputs
