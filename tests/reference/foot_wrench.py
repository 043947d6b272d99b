"""Plain-numpy statement of the compiled foot-wrench rows (``constraints.foot_wrench``): P formed in
full, the held contacts' impulse of ``jump.held_impulse``, the standing wrench by the base's
gravity (``max_speed.standing_wrenches``), the rows built foot by foot."""

import numpy as np
import pinocchio as pin

from impactqp.constraints.foot_wrench import FootWrenchLimit
from impactqp.controller.model.held_contact_description import convex_hull
from impactqp.controller.model.max_speed import sole_rows


def reference_foot_wrench_rows(limit: FootWrenchLimit, robot, terms, horizon: float, impulse_map=None, slip_dq=None):
    """(C, upper) of the active rows at the state of ``terms``: L = -(Jf M^-1 Jf^T)^-1 Jf M^-1 J^T G J,
    w the least-norm wrenches with Jf_base^T w = g_base, F = T w + L v in each foot's axes; G the
    impact's (or ``impulse_map``). The slip row is the cone's supporting plane at the wrench of
    the velocity ``slip_dq`` (default: the state's), |F_xy| >= u . F_xy."""
    M_inv, Jf, J = np.linalg.inv(terms.M), terms.held_jacobian, terms.J
    G = limit.impact.matrices(terms).impulse_map if impulse_map is None else impulse_map
    L = -np.linalg.solve(Jf @ M_inv @ Jf.T, Jf @ M_inv @ J.T) @ G @ J
    gravity = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), terms.q)
    w = limit.duration * (np.linalg.pinv(Jf[:, :robot.base_nv].T) @ gravity[:robot.base_nv])
    rows, upper = [], []
    placements = robot.frame_placements(terms.q)
    for k, contact in enumerate(robot.description.held_contacts):
        R = placements[contact.frame].rotation
        B = np.kron(np.eye(2), R)  # local wrench = B^T world wrench
        block = slice(6 * k, 6 * k + 6)
        f = R.T @ (w + L @ (terms.dq if slip_dq is None else slip_dq))[block][:3]
        u = f[:2] / np.linalg.norm(f[:2])
        local = [np.array([u[0], u[1], -contact.friction, 0.0, 0.0, 0.0])]
        sole = convex_hull(contact.sole)
        local += list(np.array([sole_rows(sole, contact.depth, e) for e in np.eye(6)]).T)
        for e in local:
            c = (B @ e) @ L[block] / terms.mass
            rows.append(c)
            upper.append((-(B @ e) @ w[block] / terms.mass - c @ terms.dq) / horizon)
    return np.array(rows), np.array(upper)
