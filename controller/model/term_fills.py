"""How a robot model fills the terms of one state (``ModelTerms``) from Pinocchio's algorithms:
the methods of :class:`ModelTermFills`, mixed into ``robot.RobotModel``.

An arm (a fixed base) has two fills. A prediction from q (``terms``) is one world-frame CRBA
pass (``pin.crba`` with ``Convention.WORLD``): the contact frame's Jacobian and placement,
(J J^T)^-1 and the locked robot's mass, centre of mass and inertia about it, the subtree inertia
``data.oYcrb`` of the root joints (what the composite-rigid-body model (20) welds); M, h and the
drift dJ6 dq are lazily filled fields (``ModelTerms.fill_lazy``), one ``computeAllTerms`` on
their first read. A controller's cycle (``update_terms``) is one ``computeAllTerms`` on the
buffer's own data (``ModelTerms.cycle_data``, made by ``empty_terms``), whose M, h, centre of mass
and contact point the buffer's fields are views of; one kernel (``model_terms.arm_cycle_terms``)
writes the contact frame's Jacobian, its drift, (J J^T)^-1, the contact point
(``ModelTerms.contact_terms``), the state and the contact rotation into the buffer
(``ModelTerms.arm_state``) from that data's joint Jacobians and checks the state; M^-1, when
read, comes from the Cholesky factor of that M (``pin.cholesky``). A floating base's fill is one
pass of the algorithms its whole-body QP needs, into its buffer (its state's check and its frames
by the kernels of ``floating_kernels``); M, h and (J J^T)^-1, which that QP does not read, on
first read.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .model_terms import (
    ACCEPTED,
    ARM_STATE_EXTRA,
    CONTACT_TERMS_EXTRA,
    NEAR_SINGULAR,
    NOT_FINITE,
    OUTSIDE_LIMITS,
    BodyTerms,
    FrameState,
    ModelTerms,
    arm_cycle_checks,
    arm_cycle_terms,
    arm_state_views,
    contact_jacobian_status,
    mirror_upper,
    pack_contact_terms,
    symmetric_inverse3_into,
)
from .floating_kernels import QUATERNION_TOLERANCE, floating_frame_arrays, floating_frames_into, floating_state_status
from .validation import BadInputError

# The contact Jacobian counts as singular when sigma_min / sigma_max falls below this ratio.
SINGULAR_RATIO = 1e-3
SINGULAR_RATIO_SQUARED = SINGULAR_RATIO**2


class SingularPostureError(BadInputError):
    """The contact Jacobian is (numerically) rank deficient at this posture."""


class ModelTermFills:
    """The fills of a robot model's ``ModelTerms`` (module docstring), for ``robot.RobotModel``:
    it reads the model's Pinocchio ``model`` and ``data``, sizes, limits, frame ids and
    ``check_state``; ``_prepare_fills`` (called once the model is built) makes the data the
    lazily filled fields and M^-1 are computed on."""

    def _prepare_fills(self) -> None:
        model = self.model
        self._body_data = model.createData()
        self._inverse_data = model.createData()
        self._root_joints = [j for j in range(1, model.njoints) if model.parents[j] == 0]
        self._held_buffer: ModelTerms | None = None  # ``held_jacobian``'s
        if self.floating:
            self._prepare_floating_frames()
        if not self.floating:  # the velocities that move the contact frame, and the checks of ``arm_cycle_terms``
            joints = model.supports[model.frames[self.contact_frame_id].parentJoint]
            columns = [c for j in joints[1:] for c in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)]
            self._contact_support = np.array(columns, dtype=np.int64)
            unlimited = np.full(self.nq, np.inf)
            support = self._contact_support
            self._cycle_checks = {
                True: arm_cycle_checks(SINGULAR_RATIO_SQUARED, self.q_min, self.q_max, support),
                False: arm_cycle_checks(SINGULAR_RATIO_SQUARED, -unlimited, unlimited, support),
                None: arm_cycle_checks(-np.inf, -unlimited, unlimited, support),  # accepts any state
            }

    def terms(self, q, dq=None, *, check_limits: bool | None = None) -> ModelTerms:
        """All model terms of the state (q, dq) (dq = 0 when None), in new arrays.

        ``check_limits`` (None: yes for a fixed base, no for a floating base, whose states come
        from its stances and simulations and whose joints its whole-body QP bounds) checks the
        joint position limits. An arm's terms raise :class:`SingularPostureError` when the
        contact Jacobian J is rank deficient (assumption 5 of the paper:
        sigma_min(J) < SINGULAR_RATIO sigma_max(J)), checked before the joint limits; every
        robot's raise :class:`InvalidStateError` for a bad or out-of-limit state.
        """
        q, dq = self.check_state(q, dq, check_limits=False)
        q, dq = q.copy(), dq.copy()  # the terms' own: M, h and M^-1 are filled later from them
        if self.floating:
            return self._fill_floating(self.empty_terms(), q, dq, bool(check_limits))
        return self._prediction_terms(q, dq, check_limits is not False)

    def update_terms(self, terms: ModelTerms, q, dq, *, check_limits: bool | None = None) -> ModelTerms:
        """``terms(q, dq)`` written into an existing ModelTerms (a controller's per-cycle
        buffer: no new object; a floating base's arrays are refilled in place), with a new
        ``stamp``. Raises like ``terms``; a refused state leaves a floating base's as it was."""
        if type(q) is not np.ndarray or type(dq) is not np.ndarray or q.dtype.char != "d" or dq.dtype.char != "d":
            q, dq = self.check_state(q, dq, check_limits=False)  # to convert into floats, or not numbers
        elif q.shape != (self.nq,) or dq.shape != (self.nv,):
            self.check_state(q, dq, check_limits=False)  # raises, naming the wrong size
        if self.base_nv:  # a floating base (an attribute: this runs every control cycle)
            return self._fill_floating(terms, q, dq, bool(check_limits))
        return self._fill_fixed(terms, q, dq, check_limits is not False)

    def _prediction_terms(self, q: np.ndarray, dq: np.ndarray, check_limits: bool) -> ModelTerms:
        """An arm's new terms of one world-frame CRBA pass (what a prediction from q needs): the
        contact frame's Jacobian and placement, (J J^T)^-1 and the locked robot's inertia (the
        subtree inertia ``data.oYcrb`` of the root joints); M, h and dJ6 dq left to their first
        read (``_lazy_dynamics``)."""
        model, data, fid = self.model, self.data, self.contact_frame_id
        pin.crba(model, data, q, pin.Convention.WORLD)
        pin.updateFramePlacement(model, data, fid)
        J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        JJt_inv = np.empty((3, 3))
        status = contact_jacobian_status(J6[:3], q, self.q_min, self.q_max, check_limits, SINGULAR_RATIO_SQUARED, JJt_inv)
        if status != ACCEPTED:
            self._refuse(J6[:3], q, dq, status, check_limits)
        placement = data.oMf[fid]
        locked = data.oYcrb[self._root_joints[0]]
        for joint in self._root_joints[1:]:
            locked = locked + data.oYcrb[joint]
        return ModelTerms(
            q, dq, None, None, J6[:3], J6, None, JJt_inv, placement.translation.copy(), placement.rotation.copy(),
            locked.lever.copy(), float(locked.mass), locked.inertia.copy(),
            compute_body=self.body_terms, compute_inverse_inertia=self.inverse_inertia, fill_lazy=self._lazy_dynamics,
        )

    def _fill_fixed(self, terms: ModelTerms, q: np.ndarray, dq: np.ndarray, check_limits: bool) -> ModelTerms:
        """An arm's terms refilled by one ``computeAllTerms`` on the buffer's own data (a
        controller's cycle: every field). M, h, the centre of mass and the contact point are
        views of that data (``cycle_data``, made at the first refill of a buffer that has none);
        (q, dq) is copied into the buffer's [q; dq] when the caller's are not writable row-major
        arrays (the kernels then see one type of array, one compiled signature), and one kernel
        (``arm_cycle_terms``) writes J6, its drift dJ6/dt dq (world-aligned: the frame's
        classical acceleration at ddq = 0), (J J^T)^-1, the contact terms, dq, the contact
        rotation and q into the buffer's state array from the data's joint Jacobians and checks
        the state (finite, contact Jacobian, limits); the inertia about the centre of mass is the data's centroidal one (a new
        array). A refused state is computed back out of the data, so the buffer stays as it
        was."""
        data = terms.cycle_data if terms.cycle_data is not None else self._attach_cycle_data(terms)
        world, centroidal, incoming, out, _, locked = terms.cycle_arrays
        if not (q.flags.writeable and dq.flags.writeable and q.flags.c_contiguous and dq.flags.c_contiguous):
            incoming[:self.nq], incoming[self.nq:] = q, dq  # the kernels read writable row-major arrays
            q, dq = incoming[:self.nq], incoming[self.nq:]
        self.pinocchio_pass(data, q, dq)
        status = arm_cycle_terms(*world, q, dq, self._cycle_checks[check_limits], out)
        if status != ACCEPTED:  # raises, or a near-singular J that the exact test clears: accept it
            try:
                J = pin.getFrameJacobian(self.model, data, self.contact_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
                self._refuse(J, q, dq, status, check_limits)
            except BadInputError:
                self.pinocchio_pass(data, terms.q, terms.dq)
                raise
            arm_cycle_terms(*world, q, dq, self._cycle_checks[None], out)
        locked[:3], terms.inertia_com[:] = terms.com, centroidal.inertia  # the locked body's [com, inertia, mass]
        return terms.refilled()

    def pinocchio_pass(self, data: pin.Data, q: np.ndarray, dq: np.ndarray) -> None:
        """The Pinocchio algorithms of one cycle's terms at (q, dq), on ``data`` (``update_terms``
        runs them on its data, then reads it; the bench's cycle floor times them alone): an arm's
        ``computeAllTerms`` and its contact frame's placement; a floating base's kinematics at
        ddq = 0 and its joints' world Jacobians, the centre of mass with its acceleration and its
        Jacobian, M^-1 (``computeMinverse``, its upper triangle) and the centroidal inertia
        (``ccrba``). None of them changes what an earlier one wrote, but the centre of mass, which
        ``ccrba`` writes again (the same to rounding)."""
        model = self.model
        if not self.base_nv:
            pin.computeAllTerms(model, data, q, dq)
            pin.updateFramePlacement(model, data, self.contact_frame_id)
            return
        pin.forwardKinematics(model, data, q, dq, self._zero_velocity)
        pin.computeJointJacobians(model, data)
        pin.centerOfMass(model, data, pin.ACCELERATION, True)  # of the kinematics above
        pin.jacobianCenterOfMass(model, data, False)  # of the Jacobians and centres of mass above
        pin.computeMinverse(model, data, q)
        pin.ccrba(model, data, q, dq)

    def _attach_cycle_data(self, terms: ModelTerms) -> pin.Data:
        """Give an arm's buffer a Pinocchio data of its own, computed at the buffer's state, and
        make its M, h, centre of mass and contact point views of that data's outputs (M's
        transpose: computeAllTerms fills both triangles, and the transpose is row-major), its J6,
        dJ6 dq, (J J^T)^-1, ``contact_terms``, dq, contact rotation and q views of one array of
        its own (``arm_state_views``) holding their present values, its locked body's [com,
        inertia, mass] one more (``ModelTerms.locked_body``, the inertia a view of it), and its
        mass the data's (a fixed base's moving mass, the same at every state); its M^-1 then
        comes from the Cholesky factor of that M."""
        drift = np.array(terms.dJ6_dq)  # first: a lazily filled drift's fill sets M and h too
        data = self.model.createData()
        self.pinocchio_pass(data, terms.q, terms.dq)
        placement = data.oMf[self.contact_frame_id]
        terms.M, terms.h, terms.com, terms.contact_point = data.M.T, data.nle, data.com[0], placement.translation
        nq, nv = self.nq, self.nv
        out = np.empty(6 * nv + ARM_STATE_EXTRA + nv + nq)
        J6, JJt_inv, _, dJ6_dq, dq, rotation, q = arm_state_views(out, nv)
        contact = out[:6 * nv + CONTACT_TERMS_EXTRA]
        contact[:] = pack_contact_terms(terms.J6, terms.JJt_inv, terms.contact_point)
        dJ6_dq[:], dq[:], rotation[:], q[:] = drift, terms.dq, placement.rotation, terms.q
        terms.J6, terms.J, terms.dJ6_dq, terms.JJt_inv = J6, J6[:3], dJ6_dq, JJt_inv
        terms.q, terms.dq, terms.contact_rotation = q, dq, rotation
        terms.mass = float(data.Ig.mass)
        incoming = np.empty(nq + nv)
        world = (data.J, data.dJ, placement.translation, placement.rotation)
        locked = np.concatenate((terms.com, np.ravel(data.Ig.inertia), [terms.mass]))
        terms.inertia_com = locked[3:12].reshape(3, 3)
        terms.cycle_data, terms.cycle_arrays = data, (world, data.Ig, incoming, out, contact, locked)
        terms.compute_inverse_inertia = lambda q: self._cholesky_inverse_inertia(data)
        return data

    def _cholesky_inverse_inertia(self, data: pin.Data) -> np.ndarray:
        """M^-1 of the M in ``data`` (both triangles) from its sparse Cholesky factor M = U D U^T
        (``pin.cholesky.decompose``, then ``computeMinv``)."""
        pin.cholesky.decompose(self.model, data)
        return pin.cholesky.computeMinv(self.model, data)

    def _refuse(self, J: np.ndarray, q: np.ndarray, dq: np.ndarray, status: int, check_limits: bool) -> None:
        """Raise for a state ``contact_jacobian_status`` (or ``arm_cycle_terms``) did not
        accept: InvalidStateError for a non-finite or huge entry, SingularPostureError when the
        exact test confirms a near-singular J, InvalidStateError (naming the joint) when q leaves
        its limits; a near-singular status that the exact test clears returns."""
        if status == NEAR_SINGULAR:
            eigenvalues = np.linalg.eigvalsh(J @ J.T)
            if not (eigenvalues[2] > 0.0 and eigenvalues[0] >= (SINGULAR_RATIO**2) * eigenvalues[2]):
                raise SingularPostureError(
                    "singular contact Jacobian at this posture (singular values ratio "
                    f"{np.sqrt(max(eigenvalues[0], 0.0) / max(eigenvalues[2], np.finfo(float).tiny)):.1e})"
                )
        if status == NOT_FINITE or status == OUTSIDE_LIMITS or check_limits:
            self.check_state(q, dq, check_limits=True)  # raises, naming the entry or the joint

    def _lazy_dynamics(self, terms: ModelTerms, name: str) -> dict[str, np.ndarray]:
        """The lazily filled fields of ``terms`` (``ModelTerms.fill_lazy``), on a data of their
        own: an arm's M, h and dJ6 dq by one ``computeAllTerms``; a floating base's M by ``crba``,
        its h by ``nonLinearEffects`` or its (J J^T)^-1 by the adjugate."""
        model, data, q, dq = self.model, self._body_data, terms.q, terms.dq
        if name == "JJt_inv":
            JJt_inv = np.empty((3, 3))
            symmetric_inverse3_into(terms.J @ terms.J.T, JJt_inv)
            return {"JJt_inv": JJt_inv}
        if self.floating:
            if name == "M":
                M = np.empty((self.nv, self.nv))
                mirror_upper(pin.crba(model, data, q), M)
                return {"M": M}
            return {"h": pin.nonLinearEffects(model, data, q, dq).copy()}
        pin.computeAllTerms(model, data, q, dq)
        pin.updateFramePlacement(model, data, self.contact_frame_id)
        drift = pin.getFrameClassicalAcceleration(model, data, self.contact_frame_id, pin.LOCAL_WORLD_ALIGNED)
        return {"M": data.M.copy(), "h": data.nle.copy(), "dJ6_dq": drift.vector.copy()}

    def inverse_inertia(self, q: np.ndarray) -> np.ndarray:
        """M^-1 at q (Pinocchio's ``computeMinverse``, both triangles), on a data of its own."""
        M_inv = np.empty((self.nv, self.nv))
        mirror_upper(pin.computeMinverse(self.model, self._inverse_data, q), M_inv)
        return M_inv

    def empty_terms(self) -> ModelTerms:
        """A ModelTerms for ``update_terms`` to refill (a controller's per-cycle buffer): an arm's
        with its own Pinocchio data (``_attach_cycle_data``) at the neutral configuration at rest,
        the fields it does not view unset; a floating base's of unset arrays, its M, h and
        (J J^T)^-1 on their first read (``_lazy_dynamics``)."""
        nv = self.nv
        J6 = np.empty((6, nv))
        if not self.floating:
            terms = ModelTerms(
                pin.neutral(self.model), np.zeros(nv), None, None, J6[:3], J6, np.empty(6), np.empty((3, 3)),
                None, None, None, 0.0, np.empty((3, 3)), compute_body=self.body_terms,
            )
            self._attach_cycle_data(terms)
            return terms
        count, held = 1 + len(self.held_frame_ids), len(self.held_frame_ids)
        stacked = J6s, drifts, positions, rotations = floating_frame_arrays(count + len(self.frame_ids), nv)
        frames = {
            name: FrameState(positions[k], rotations[k], J6s[k], drifts[k])
            for k, name in enumerate(self.frame_ids, start=count)
        }
        return ModelTerms(
            np.empty(self.nq), np.empty(nv), None, None, J6s[0, :3], J6s[0], drifts[0],
            None, positions[0], rotations[0], np.empty(3), 0.0, np.empty((3, 3)),
            J6s[1:count].reshape(6 * held, nv), drifts[1:count].reshape(6 * held),
            BodyTerms(np.empty((nv, nv)), np.empty((3, nv)), np.empty(3), frames),
            fill_lazy=self._lazy_dynamics, frame_arrays=stacked,
        )

    def held_jacobian(self, q: np.ndarray) -> np.ndarray:
        """A floating base's held contacts' Jacobian Jf at the configuration q: ``terms(q)``'s
        ``held_jacobian``, by the same kinematics and kernel (``floating_frames_into``), without
        the rest of the terms (M^-1, the centroidal inertia). A view of a buffer of its own that
        the next call overwrites; q is trusted (a simulated plant's)."""
        buffer = self._held_buffer
        if buffer is None:
            buffer = self._held_buffer = self.empty_terms()
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, self._zero_velocity, self._zero_velocity)
        pin.computeJointJacobians(model, data)
        joints, frames = self._floating_frames
        floating_frames_into(data.J, joints, frames, buffer.frame_arrays)
        return buffer.held_jacobian

    def _prepare_floating_frames(self) -> None:
        """The fixed inputs of a floating base's ``floating_frames_into``, for its contact frame,
        its held contacts and its named frames (``ModelTerms.frame_arrays``' order): each frame's
        joint's placement, twist and acceleration (views of the model's data, which its fill's
        kinematics rewrite in place), its placement in that joint's axes, and the velocities
        that move that joint; and views of the data's centre of mass, its acceleration and the
        centroidal inertia, which ``pinocchio_pass`` rewrites in place too."""
        model, data = self.model, self.data
        frame_ids = [self.contact_frame_id, *self.held_frame_ids, *self.frame_ids.values()]
        local = np.empty((len(frame_ids), 4, 3))
        support = np.zeros((len(frame_ids), self.nv), dtype=np.uint8)
        joints = []
        for f, frame_id in enumerate(frame_ids):
            frame = model.frames[frame_id]
            i = frame.parentJoint
            local[f, :3], local[f, 3] = frame.placement.rotation, frame.placement.translation
            for j in model.supports[i][1:]:
                support[f, model.joints[j].idx_v:model.joints[j].idx_v + model.joints[j].nv] = 1
            placement, twist, acceleration = data.oMi[i], data.v[i], data.a[i]
            joints.append((
                placement.rotation, placement.translation, twist.linear, twist.angular,
                acceleration.linear, acceleration.angular,
            ))
        self._floating_frames = tuple(joints), (local, support)
        self._floating_outputs = data.com[0], data.acom[0], data.Ig  # views of what the pass rewrites in place

    def _fill_floating(self, terms: ModelTerms, q: np.ndarray, v: np.ndarray, check_limits: bool) -> ModelTerms:
        """One pass of Pinocchio's algorithms at (q, v) (float arrays of the model's sizes) into
        ``terms``: the state checked and copied by ``floating_state_status``, the kinematics at
        ddq = 0 and the joints' world Jacobians, the frames written from them by
        ``floating_frames_into`` (no new array), the centre of mass, its Jacobian and drift,
        M^-1, and the mass and the inertia about the centre of mass (the centroidal inertia of
        ``ccrba``). M, h and (J J^T)^-1, which the whole-body QP does not read (its rows read
        M^-1), are left to their first read. A refused state leaves ``terms`` as it was."""
        if check_limits:
            self.check_state(q, v, check_limits=True)
        if floating_state_status(q, v, self.base_nq, QUATERNION_TOLERANCE, terms.q, terms.dq) != ACCEPTED:
            q, v = self.check_state(q, v, check_limits=False)  # raises, naming the entry
            terms.q[:], terms.dq[:] = q, v
        data, body = self.data, terms.body
        self.pinocchio_pass(data, terms.q, terms.dq)
        joints, frames = self._floating_frames
        floating_frames_into(data.J, joints, frames, terms.frame_arrays)
        com, com_acceleration, centroidal = self._floating_outputs
        terms.com[:], body.dJcom_dq[:], body.Jcom[:] = com, com_acceleration, data.Jcom
        mirror_upper(data.Minv, body.M_inv)
        terms.mass, terms.inertia_com[:] = centroidal.mass, centroidal.inertia
        return terms.refilled(pending=("M", "h", "JJt_inv"))

    def body_terms(self, q: np.ndarray, dq: np.ndarray) -> BodyTerms:
        """M^-1, Jcom, dJcom dq and the named frames of the state (q, dq) (``BodyTerms``), on a
        data of their own: what a fixed base's terms compute on first use."""
        model, data = self.model, self._body_data
        pin.forwardKinematics(model, data, q, dq, self._zero_velocity)
        pin.computeJointJacobians(model, data)
        pin.updateFramePlacements(model, data)
        world = pin.LOCAL_WORLD_ALIGNED
        frames = {}
        for name, frame_id in self.frame_ids.items():
            placement = data.oMf[frame_id]
            frames[name] = FrameState(
                placement.translation.copy(), placement.rotation.copy(),
                pin.getFrameJacobian(model, data, frame_id, world),
                pin.getFrameClassicalAcceleration(model, data, frame_id, world).vector.copy(),
            )
        pin.centerOfMass(model, data, pin.ACCELERATION, True)
        dJcom_dq = data.acom[0].copy()
        Jcom = pin.jacobianCenterOfMass(model, data, False).copy()
        return BodyTerms(self.inverse_inertia(q), Jcom, dJcom_dq, frames)
