"""Vectorised jump prediction over many states at once, for datasets.

Pinocchio works one state at a time; for N states the per-call Python overhead dominates.
:class:`BatchKinematics` reads the kinematic tree and link inertias from the Pinocchio model and
evaluates, for N joint vectors at once with NumPy, the same terms as ``PandaModel.terms``: the
contact Jacobian J, the joint-space inertia M = sum_k (Jv_k^T m_k Jv_k + Jw_k^T I_k Jw_k), the
centre of mass, the moving mass and the locked-robot inertia about the centre of mass.
:func:`predict_batch` hands them to :func:`predict_from_terms`, the maps of
:mod:`controller.model.jump`'s table for N states at once; the CRB prediction of a predicted
impulse, which needs none of M, is one compiled loop over the states instead
(``crb_prediction.CrbPredictor.predict_batch``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from .crb_prediction import CrbPredictor
from . import validation
from .jump import METHODS, crb_inverse_inertia
from .robot import PandaModel
from .validation import BadInputError


@dataclass(frozen=True)
class BatchTerms:
    """Model terms of N states (leading axis N), world-aligned as in ``ModelTerms``."""

    J: np.ndarray  # (N, 3, nv) contact-point Jacobian
    contact_point: np.ndarray  # (N, 3)
    com: np.ndarray  # (N, 3)
    mass: float
    inertia_com: np.ndarray  # (N, 3, 3)
    joint_axes: np.ndarray  # (N, nv, 3) world axes z_k of the joints
    joint_origins: np.ndarray  # (N, nv, 3)
    link_com: np.ndarray  # (N, nv, 3)
    link_inertia_world: np.ndarray  # (N, nv, 3, 3) about each link's centre of mass
    link_masses: np.ndarray  # (nv,)

    def rows(self, index: np.ndarray) -> BatchTerms:
        """The terms of the states ``index`` (an index or mask along N), without evaluating
        them again; M comes along when it was already computed."""
        per_state = {
            f.name: getattr(self, f.name)[index] for f in fields(self) if f.name not in ("mass", "link_masses")
        }
        subset = BatchTerms(mass=self.mass, link_masses=self.link_masses, **per_state)
        if "M" in self.__dict__:
            subset.__dict__["M"] = self.M[index]
        return subset

    @cached_property
    def M(self) -> np.ndarray:
        """M (N, nv, nv) = sum_k Jv_k^T m_k Jv_k + Jw_k^T I_k Jw_k over the links k."""
        N, n = self.J.shape[0], self.J.shape[2]
        lower = np.tril(np.ones((n, n)))  # [k, j] = 1 when joint j moves link k
        lever = self.link_com[:, :, None, :] - self.joint_origins[:, None, :, :]  # (N, k, j, 3)
        axes = np.broadcast_to(self.joint_axes[:, None], (N, n, n, 3))
        Jv = np.cross(axes, lever) * lower[None, :, :, None]  # (N, k, j, 3)
        Jw = axes * lower[None, :, :, None]
        M = np.einsum("k,nkia,nkja->nij", self.link_masses, Jv, Jv, optimize=True)
        M += np.einsum("nkia,nkab,nkjb->nij", Jw, self.link_inertia_world, Jw, optimize=True)
        return M


class BatchKinematics:
    """Forward kinematics and inertial terms of a serial revolute-z chain, for N states."""

    def __init__(self, robot: PandaModel):
        model = robot.model
        for i in range(1, model.njoints):
            if model.joints[i].shortname() != "JointModelRZ" or model.parents[i] != i - 1:
                raise ValueError("BatchKinematics needs a serial chain of revolute-z joints")
        self.robot = robot
        self.R_joint = np.array([model.jointPlacements[i].rotation for i in range(1, model.njoints)])
        self.p_joint = np.array([model.jointPlacements[i].translation for i in range(1, model.njoints)])
        self.masses = np.array([model.inertias[i].mass for i in range(1, model.njoints)])
        self.levers = np.array([model.inertias[i].lever for i in range(1, model.njoints)])
        self.inertias = np.array([model.inertias[i].inertia for i in range(1, model.njoints)])
        frame = model.frames[robot.contact_frame_id]
        if frame.parentJoint != model.njoints - 1:
            raise ValueError("the contact frame must be attached to the last joint")
        self.p_contact = frame.placement.translation.copy()
        self.R_contact = frame.placement.rotation.copy()
        self.total_mass = float(self.masses.sum())
        self.crb = CrbPredictor(robot)

    def _chain(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint frames of N states: rotations Rs (N, nv, 3, 3) and origins ps (N, nv, 3)."""
        Q = np.asarray(Q, dtype=float)
        n = self.robot.nq
        if Q.ndim != 2 or Q.shape[1] != n:
            raise BadInputError(f"Q must have shape (N, {n}), got {Q.shape}")
        if not np.all(np.isfinite(Q)):
            raise BadInputError("Q contains a non-finite value")
        N = Q.shape[0]
        c, s = np.cos(Q), np.sin(Q)
        Rs = np.empty((N, n, 3, 3))
        ps = np.empty((N, n, 3))
        R, p = np.broadcast_to(np.eye(3), (N, 3, 3)), np.zeros((N, 3))
        for k in range(n):
            p = p + R @ self.p_joint[k]
            R = R @ self.R_joint[k]
            # R Rz(q_k): rotate the first two columns about the third.
            x, y = R[:, :, 0], R[:, :, 1]
            ck, sk = c[:, k, None], s[:, k, None]
            Rs[:, k, :, 0] = ck * x + sk * y
            Rs[:, k, :, 1] = ck * y - sk * x
            Rs[:, k, :, 2] = R[:, :, 2]
            R = Rs[:, k]
            ps[:, k] = p
        return Rs, ps

    def contact_frames(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Contact point p (N, 3), tool axis z (N, 3) (hand z) and world-aligned frame Jacobian
        J6 = [Jv; Jw] (N, 6, nv) of N states: Jv_k = z_k x (p - o_k), Jw_k = z_k."""
        Rs, ps = self._chain(Q)
        axes = Rs[:, :, :, 2]
        contact = ps[:, -1] + Rs[:, -1] @ self.p_contact
        tool_axis = Rs[:, -1] @ self.R_contact[:, 2]
        J6 = np.concatenate(
            [np.swapaxes(np.cross(axes, contact[:, None, :] - ps), 1, 2), np.swapaxes(axes, 1, 2)], axis=1
        )
        return contact, tool_axis, J6

    def terms(self, Q: np.ndarray) -> BatchTerms:
        Rs, ps = self._chain(Q)
        axes = Rs[:, :, :, 2]
        link_com = ps + np.einsum("nkab,kb->nka", Rs, self.levers)
        contact = ps[:, -1] + Rs[:, -1] @ self.p_contact
        com = np.einsum("k,nka->na", self.masses, link_com) / self.total_mass
        I_world = Rs @ self.inertias @ np.swapaxes(Rs, 2, 3)
        r = link_com - com[:, None, :]
        mr = self.masses[:, None] * r
        parallel_axis = np.einsum("nka,nka->n", mr, r)[:, None, None] * np.eye(3)
        parallel_axis -= np.swapaxes(mr, 1, 2) @ r
        inertia_com = I_world.sum(axis=1) + parallel_axis
        J = np.swapaxes(np.cross(axes, contact[:, None, :] - ps), 1, 2)
        return BatchTerms(
            J, contact, com, self.total_mass, inertia_com, axes, ps, link_com, I_world, self.masses
        )


def predict_from_terms(
    terms,
    normals: np.ndarray,
    pre_impact_velocities: np.ndarray,
    restitution: float = 0.0,
    method: str = "crb",
    impulses: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Jumps (N, nv) and impulses (N, 3) of the predictor ``method`` for N states at once.

    ``terms`` are batched model terms (``controller.model.batch.BatchTerms``: J (N, 3, nv),
    contact point, centre of mass, mass, inertia about the centre of mass and M (N, nv, nv));
    ``normals`` and ``pre_impact_velocities`` are (N, 3) or (3,) arrays (world frame); with
    ``impulses`` (N, 3) the measured impulses replace the predicted ones. The maps are those of
    the table of the module docstring, with M^-1 J^T by two triangular solves of the Cholesky
    factor of M (no M at all for crb).
    """
    if method not in METHODS:
        raise BadInputError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")
    N = terms.J.shape[0]
    n = validation.vector_rows(validation.unit_normals(normals), N, "the surface normals")
    restitution = validation.restitution(restitution)
    v = validation.vector_rows(pre_impact_velocities, N, "the pre-impact velocities")
    J, Jt = terms.J, np.swapaxes(terms.J, 1, 2)
    if method == "crb":
        W = crb_inverse_inertia(terms)
    else:
        L = np.linalg.cholesky(terms.M)
        Y = np.linalg.solve(L, Jt)
        MinvJt = np.linalg.solve(np.swapaxes(L, 1, 2), Y)  # M^-1 J^T by two triangular solves
        W = J @ MinvJt
    if impulses is None:
        if method in ("classical", "classical_normal"):
            impulse = -(1.0 + restitution) * np.linalg.solve(W, v[..., None])[..., 0]
            if method == "classical_normal":
                impulse = np.einsum("na,na->n", n, impulse)[:, None] * n
        else:
            nWn = np.einsum("na,nab,nb->n", n, W, n)
            iota_n = -(1.0 + restitution) * np.einsum("na,na->n", n, v) / nWn
            impulse = iota_n[:, None] * n
    else:
        impulse = validation.vector_rows(impulses, N, "the impulses")
    if method in ("classical", "classical_normal"):
        dq = (MinvJt @ impulse[..., None])[..., 0]
    else:
        Wi = (W @ impulse[..., None])[..., 0]
        dq = (Jt @ np.linalg.solve(J @ Jt, Wi[..., None]))[..., 0]
    return dq, np.array(impulse)


def predict_batch(
    kinematics: BatchKinematics,
    Q: np.ndarray,
    normals: np.ndarray,
    pre_impact_velocities: np.ndarray,
    restitution: float = 0.0,
    method: str = "crb",
    impulses: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Jumps (N, nv) and impulses (N, 3) of one predictor for N states.

    ``normals`` and ``pre_impact_velocities`` are (N, 3) or (3,) arrays (world frame); with
    ``impulses`` (N, 3) the measured impulses replace the predicted ones.
    """
    if method == "crb" and impulses is None:
        return kinematics.crb.predict_batch(Q, normals, pre_impact_velocities, restitution)
    Q = validation.state_rows(Q, kinematics.robot.nq, "Q")
    return predict_from_terms(kinematics.terms(Q), normals, pre_impact_velocities, restitution, method, impulses)
