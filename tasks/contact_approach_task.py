"""Contact-approach task: move the contact point towards a surface at a reference speed."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import tangential_velocity as tangential_velocity_along
from impactqp.controller.model.validation import MAX_CONTACT_SPEED, finite_array, number_in_range, task_gain
from impactqp.controller.model.validation import rotation_matrix, unit_normal

from .task import OrientationHold, Task, rotation_log


class ContactApproachTask(Task):
    """Drive the contact point along -n at ``speed`` while holding tangential motion and
    orientation.

    With v = J dq the contact-point velocity and w the angular velocity of the contact frame,
    the desired frame acceleration is

        a_lin* = k_v (v* - v),        v* = -speed n + v_t (v_t tangential, n.v_t = 0)
        a_ang* = k_R log(R* R^T) - d_R w

    and the rows are J6 ddq = a* - dJ6 dq, expressed in the surface frame: one normal row
    weighted ``normal_weight``, two tangential rows weighted ``tangential_weight``, three
    orientation rows weighted ``orientation.weight`` (``OrientationHold``). With strong tangential and orientation
    weights the joint velocity stays close to dq = speed d, d = J6+ [-n; 0], the approach
    direction assumed by the closed-form maximum speed (docs/qp-constraints.md). The impact-aware
    constraints cap the normal speed the task actually gets.
    """

    name = "contact_approach"
    rows = 6

    def __init__(
        self,
        normal,
        speed: float,
        tangential_velocity=(0.0, 0.0, 0.0),
        velocity_gain: float = 20.0,
        normal_weight: float = 1.0,
        tangential_weight: float = 100.0,
        orientation: OrientationHold = OrientationHold(),
        target_rotation=None,
    ):
        normal = unit_normal(normal)
        tangential_velocity = tangential_velocity_along(tangential_velocity, normal)
        speed = number_in_range(speed, 0.0, MAX_CONTACT_SPEED, "the approach speed (along -n)", "m/s")
        for label, value in (("velocity_gain", velocity_gain), ("normal_weight", normal_weight),
                             ("tangential_weight", tangential_weight)):
            task_gain(value, label)
        if not isinstance(orientation, OrientationHold):
            raise TypeError("orientation must be an OrientationHold")
        self._reference = np.zeros(1, APPROACH_REFERENCE)  # what the kernel reads; the fields below view it
        self._kernel_reference = self._reference.view(np.float64)  # the same numbers, flat
        # Surface frame: rows of `basis` are n, t1, t2 (world axes).
        t1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
        t1 /= np.linalg.norm(t1)
        self.basis = self._reference["basis"][0]
        self.basis[:] = np.vstack([normal, t1, np.cross(normal, t1)])
        self.normal = normal
        self.speed = float(speed)
        self.velocity_gain = float(velocity_gain)
        self._reference_acceleration = self._reference["reference_acceleration"][0]
        self.reference_velocity = -self.speed * normal + tangential_velocity
        self.orientation_stiffness = orientation.stiffness
        self.orientation_damping = orientation.damping_gain()
        self.weight = np.array(
            [normal_weight, tangential_weight, tangential_weight] + [orientation.weight] * 3, dtype=float
        )
        self._target_rotation = None
        self.target_rotation = (
            None if target_rotation is None else rotation_matrix(target_rotation, "target_rotation")
        )
        self._twist_gain = self._reference["twist_gain"][0]
        self._twist_gain[:] = np.repeat([-self.velocity_gain, -self.orientation_damping], 3)
        self._rotation_configured = self.target_rotation is not None

    @property
    def reference_velocity(self) -> np.ndarray:
        """v* (world, m/s); setting it also sets the feed-forward k_v v* of the rows."""
        return self._reference_velocity

    @reference_velocity.setter
    def reference_velocity(self, value) -> None:
        self._reference_velocity = finite_array(value, (3,), "reference_velocity")
        np.multiply(self.velocity_gain, self._reference_velocity, out=self._reference_acceleration)

    @property
    def orientation_stiffness(self) -> float:
        """k_R (1/s^2)."""
        return float(self._reference["orientation_stiffness"][0])

    @orientation_stiffness.setter
    def orientation_stiffness(self, value: float) -> None:
        self._reference["orientation_stiffness"] = float(value)

    @property
    def target_rotation(self) -> np.ndarray | None:
        """R* (world), None until given or captured at ``reset``."""
        return self._target_rotation

    @target_rotation.setter
    def target_rotation(self, value) -> None:
        if value is None:
            self._target_rotation = None
            return
        self._target_rotation = self._reference["target_rotation"][0]
        self._target_rotation[:] = value

    def reset(self, terms: ModelTerms) -> None:
        if not self._rotation_configured:
            self.target_rotation = terms.contact_rotation.copy()

    def kernel_parameters(self) -> np.ndarray:
        """The kernel's reference (an ``APPROACH_REFERENCE`` record's numbers) and the weights (6)."""
        return np.concatenate([self._kernel_reference, self.weight])

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        surface_frame_approach_rows(terms.J6, terms.dq, terms.dJ6_dq, terms.contact_rotation, self._kernel_reference, A, b)


APPROACH_REFERENCE = np.dtype([
    ("target_rotation", np.float64, (3, 3)),
    ("basis", np.float64, (3, 3)),
    ("twist_gain", np.float64, (6,)),
    ("reference_acceleration", np.float64, (3,)),
    ("orientation_stiffness", np.float64),
])
"""What ``ContactApproachTask`` asks of its contact frame, one record its kernel reads (a compiled
kernel takes a record, not a dataclass): R* (world), the rows n, t1, t2 of the surface frame
(world axes), the gain [-k_v] * 3 + [-d_R] * 3 on the frame's twist [v; w], k_v v* (world) and
k_R. Its fields are float64 in this order with no padding: the kernel reads the record's numbers
as one flat array of ``APPROACH_REFERENCE_SIZE``."""

APPROACH_REFERENCE_SIZE = APPROACH_REFERENCE.itemsize // 8
"""How many numbers an ``APPROACH_REFERENCE`` record holds."""


@njit(cache=True)
def surface_frame_approach_rows(J6, dq, dJ6_dq, rotation, reference, A, b):
    """Kernel of ``ContactApproachTask``: b = gain * (J6 dq) + [k_v v*; k_R log(R* R^T)] - dJ6 dq,
    then the linear rows (of A = J6 and b) expressed in the surface frame; R = ``rotation``, the
    rest ``reference``: an ``APPROACH_REFERENCE`` record's numbers, flat (R*, basis, twist gain,
    k_v v*, k_R)."""
    target_rotation, basis = reference[0:9].reshape((3, 3)), reference[9:18].reshape((3, 3))
    twist_gain, reference_acceleration, orientation_stiffness = reference[18:24], reference[24:27], reference[27]
    twist = np.zeros(6)  # J6 dq in plain loops (no BLAS call at this size)
    for i in range(6):
        for j in range(dq.shape[0]):
            twist[i] += J6[i, j] * dq[j]
    log = np.empty(3)
    rotation_log(target_rotation, rotation, log)
    linear = np.empty(3)
    for i in range(3):
        linear[i] = twist_gain[i] * twist[i] + reference_acceleration[i] - dJ6_dq[i]
        b[3 + i] = twist_gain[3 + i] * twist[3 + i] + orientation_stiffness * log[i] - dJ6_dq[3 + i]
    for i in range(3):
        b[i] = basis[i, 0] * linear[0] + basis[i, 1] * linear[1] + basis[i, 2] * linear[2]
        for j in range(J6.shape[1]):
            A[i, j] = basis[i, 0] * J6[0, j] + basis[i, 1] * J6[1, j] + basis[i, 2] * J6[2, j]
            A[3 + i, j] = J6[3 + i, j]
