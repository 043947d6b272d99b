"""Common interface of the QP tasks.

A task is a weighted least-squares residual on the joint acceleration ddq:

    cost = sum_i weight_i (A_i ddq - b_i)^2

``compute`` returns the rows (A, b, weight) of one state. Tasks written on a frame use the
world-aligned frame Jacobian J6 and its drift dJ6 dq (``ModelTerms``), so a desired frame
acceleration a* gives the rows J6 ddq = a* - dJ6 dq. Targets left unspecified are captured from
the state given to ``reset`` (the controller calls it at its first cycle and on ``reset``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import math

import numpy as np
from numba import njit

from impactqp.controller.model.model_terms import ModelTerms
from impactqp.controller.model.validation import task_gain


class TaskRows(NamedTuple):
    """Residual rows A ddq - b with one weight per row."""

    A: np.ndarray
    b: np.ndarray
    weight: np.ndarray


class Task:
    """A named least-squares objective with ``rows`` rows and one weight per row (``weight``).

    A task writes its rows into arrays it is given (``compute_into``): a controller hands it
    views of the stacked task data, so nothing is copied; ``compute`` returns them in new
    arrays. Where a class has a compiled kernel (numba), ``compute_into`` calls it (its
    plain-numpy statement is in the tests, ``tests/reference/tasks.py``), and its
    ``kernel_parameters()`` give that kernel's parameters and the weights in one flat array, the
    form a controller's compiled cycle plan reads (``controller.qp.cycle_plan``).
    """

    name: str = ""
    rows: int = 0
    weight: np.ndarray
    parameter_edits = 0
    """Assignments to the attributes of any task so far: a compiled cycle plan
    (``controller.qp.cycle_plan``) packs its tasks' ``kernel_parameters`` again when it changed
    (a parameter is set by assignment; an array changed in place is not seen)."""

    def __setattr__(self, name: str, value) -> None:
        object.__setattr__(self, name, value)
        Task.parameter_edits += 1

    def reset(self, terms: ModelTerms) -> None:
        """Capture the targets that were left unspecified from the state ``terms``."""

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        """Write the rows A (rows x number of velocities) and b of this state."""
        raise NotImplementedError

    def compute(self, terms: ModelTerms) -> TaskRows:
        A, b = np.empty((self.rows, terms.dq.shape[0])), np.empty(self.rows)  # one column per velocity
        self.compute_into(terms, A, b)
        return TaskRows(A, b, self.weight)


def rotation_error(target: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Rotation vector log(R* R^T) in world axes: the angular displacement from R to R*
    (the compiled :func:`rotation_log`)."""
    out = np.empty(3)
    rotation_log(target, rotation, out)
    return out


def critical_damping(stiffness: float) -> float:
    return 2.0 * float(np.sqrt(stiffness))


@dataclass(frozen=True)
class OrientationHold:
    """How a task on the contact frame holds its orientation: a_ang* = k_R log(R* R^T) - d_R w on
    its three orientation rows, each weighted ``weight``; k_R = ``stiffness``, d_R = ``damping``
    (None: critical damping 2 sqrt(k_R)). A configuration's task gives them as
    ``orientation_stiffness``, ``orientation_damping`` and ``orientation_weight``
    (:data:`ORIENTATION_PARAMETERS`)."""

    stiffness: float = 100.0
    damping: float | None = None
    weight: float = 100.0

    def __post_init__(self):
        task_gain(self.stiffness, "orientation_stiffness")
        if self.damping is not None:
            task_gain(self.damping, "orientation_damping")
        task_gain(self.weight, "orientation_weight")

    def damping_gain(self) -> float:
        """d_R."""
        return critical_damping(self.stiffness) if self.damping is None else float(self.damping)

    @classmethod
    def taken_from(cls, parameters: dict) -> OrientationHold:
        """The hold of a configuration's task ``parameters``: their ``ORIENTATION_PARAMETERS``
        keys, taken out of the dict."""
        return cls(**{name: parameters.pop(key) for key, name in ORIENTATION_PARAMETERS.items() if key in parameters})


ORIENTATION_PARAMETERS = {
    "orientation_stiffness": "stiffness", "orientation_damping": "damping", "orientation_weight": "weight",
}
"""A configuration's task parameter of each field of :class:`OrientationHold`."""


@njit(cache=True)
def rotation_log(target, rotation, out):
    """Kernel of ``rotation_error``: the rotation vector of R = R* R^T into ``out``.

    With c = (tr R - 1) / 2 = cos(theta) and v = vee(R - R^T) = 2 sin(theta) a (a the unit
    axis): theta = atan2(|v| / 2, c); log R = theta / (2 sin theta) v, or v / 2 to third order
    near the identity. Near theta = pi, where v vanishes, the axis comes from
    (R + R^T) / 2 - c I = (1 - c) a a^T (its largest diagonal entry), signed along v.
    """
    R = np.empty((3, 3))  # R* R^T in plain loops (a BLAS call from compiled code costs more at 3 x 3)
    for i in range(3):
        for j in range(3):
            R[i, j] = target[i, 0] * rotation[j, 0] + target[i, 1] * rotation[j, 1] + target[i, 2] * rotation[j, 2]
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    vx, vy, vz = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    s = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
    theta = math.atan2(s, c)
    if theta < 1e-6:
        out[0], out[1], out[2] = 0.5 * vx, 0.5 * vy, 0.5 * vz
    elif c > -0.7:
        factor = 0.5 * theta / s
        out[0], out[1], out[2] = factor * vx, factor * vy, factor * vz
    else:
        B = 0.5 * (R + R.T)
        k = 0
        for i in range(1, 3):
            if B[i, i] > B[k, k]:
                k = i
        scale = 1.0 / math.sqrt((B[k, k] - c) * (1.0 - c))
        ax, ay, az = B[0, k] * scale, B[1, k] * scale, B[2, k] * scale
        if k == 0:
            ax = (B[0, 0] - c) * scale
        elif k == 1:
            ay = (B[1, 1] - c) * scale
        else:
            az = (B[2, 2] - c) * scale
        if ax * vx + ay * vy + az * vz < 0.0:
            ax, ay, az = -ax, -ay, -az
        out[0], out[1], out[2] = theta * ax, theta * ay, theta * az
