"""Plain-numpy statements of the G1's model terms (``RobotModel.terms``) and of the
held-contact jump maps (``JumpModel.unit_matrices`` with held contacts) before their compiled kernels: the terms from
independent Pinocchio calls, the maps with the full constrained inverse inertia P, the feet-held
right inverse J#."""

import numpy as np
import pinocchio as pin

from impactqp.controller.model.jump import JumpMatrices, crb_inverse_inertia
from impactqp.controller.model.model_terms import BodyTerms, FrameState, ModelTerms


def _frame_state(robot, data, frame_id: int) -> FrameState:
    world = pin.LOCAL_WORLD_ALIGNED
    placement = data.oMf[frame_id]
    return FrameState(
        placement.translation.copy(), placement.rotation.copy(),
        pin.getFrameJacobian(robot.model, data, frame_id, world),
        pin.getFrameClassicalAcceleration(robot.model, data, frame_id, world).vector.copy(),
    )


def _symmetric(upper: np.ndarray) -> np.ndarray:
    return np.triu(upper) + np.triu(upper, 1).T


def reference_terms(robot, q, v) -> ModelTerms:
    """``RobotModel.terms(q, v)`` on a fresh Pinocchio data."""
    model, data = robot.model, robot.model.createData()
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.computeJointJacobians(model, data)
    pin.updateFramePlacements(model, data)
    contact = _frame_state(robot, data, robot.contact_frame_id)
    feet = [_frame_state(robot, data, f) for f in robot.held_frame_ids]
    torso = _frame_state(robot, data, robot.frame_ids["torso"])
    M = _symmetric(pin.crba(model, data, q))
    M_inv = _symmetric(pin.computeMinverse(model, data, q))
    pin.centerOfMass(model, data, q, v, np.zeros(model.nv))
    com, dJcom_dq = data.com[0].copy(), data.acom[0].copy()
    Jcom = pin.jacobianCenterOfMass(model, data, q).copy()
    pin.ccrba(model, data, q, v)
    mass, inertia = float(data.Ig.mass), data.Ig.inertia.copy()
    h = pin.rnea(model, data, q, v, np.zeros(model.nv))
    J = contact.J6[:3]
    return ModelTerms(
        q.copy(), v.copy(), M, h, J, contact.J6, contact.dJ6_dq, np.linalg.inv(J @ J.T), contact.position,
        contact.rotation, com, mass, inertia, np.vstack([f.J6 for f in feet]), np.concatenate([f.dJ6_dq for f in feet]),
        BodyTerms(M_inv, Jcom, dJcom_dq, {"torso": torso}),
    )


def reference_jump_maps(terms, method: str, normal: np.ndarray, c_r: float) -> JumpMatrices:
    """``JumpModel.unit_matrices`` with held contacts (``jump_kernels.held_contact_maps``):
    P_f = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 formed in full."""
    J, Jf = terms.J, terms.held_jacobian
    MiJf = terms.M_inv @ Jf.T
    P = terms.M_inv - MiJf @ np.linalg.solve(Jf @ MiJf, MiJf.T)
    PJt = P @ J.T
    W_gm = J @ PJt
    W_gm = 0.5 * (W_gm + W_gm.T)
    if method == "classical":
        G = -(1.0 + c_r) * np.linalg.inv(W_gm)
        K = PJt
    else:
        W = W_gm if method == "gm" else crb_inverse_inertia(terms)
        G = (-(1.0 + c_r) / (normal @ W @ normal)) * np.outer(normal, normal)
        NJt = J.T - Jf.T @ np.linalg.solve(Jf @ Jf.T, Jf @ J.T)
        K = NJt @ np.linalg.inv(J @ NJt) @ W
    return JumpMatrices(K @ (G @ J), J.T @ G @ J, G, terms.Jcom @ PJt)


def feet_held_pinv(J: np.ndarray, Jf: np.ndarray) -> np.ndarray:
    """J# = N J^T (J N J^T)^-1 (``jump_kernels``' module docstring): the least-norm dv with
    J dv = x, Jf dv = 0, which ``held_contact_maps`` computes inside its kernel."""
    NJt = J.T - Jf.T @ np.linalg.solve(Jf @ Jf.T, Jf @ J.T)
    return NJt @ np.linalg.inv(J @ NJt)
