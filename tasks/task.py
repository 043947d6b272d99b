"""Common interface of the QP tasks.

A task is a weighted least-squares residual on the joint acceleration ddq:

    cost = sum_i weight_i (A_i ddq - b_i)^2

``compute`` returns the rows (A, b, weight) of one state. Tasks written on a frame use the
world-aligned frame Jacobian J6 and its drift dJ6 dq (``ModelTerms``), so a desired frame
acceleration a* gives the rows J6 ddq = a* - dJ6 dq. Targets left unspecified are captured from
the state given to ``reset`` (the controller calls it at its first cycle and on ``reset``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from impactqp.controller.model.robot import ModelTerms
from impactqp.controller.model.validation import BadInputError


class TaskRows(NamedTuple):
    """Residual rows A ddq - b with one weight per row."""

    A: np.ndarray
    b: np.ndarray
    weight: np.ndarray


class Task:
    """A named least-squares objective with ``rows`` rows and one weight per row (``weight``).

    A task writes its rows into arrays it is given (``compute_into``): a controller hands it
    views of the stacked task data, so nothing is copied; ``compute`` returns them in new
    arrays.
    """

    name: str = ""
    rows: int = 0
    weight: np.ndarray

    def reset(self, terms: ModelTerms) -> None:
        """Capture the targets that were left unspecified from the state ``terms``."""

    def compute_into(self, terms: ModelTerms, A: np.ndarray, b: np.ndarray) -> None:
        """Write the rows A (rows x 7) and b of this state."""
        raise NotImplementedError

    def compute(self, terms: ModelTerms) -> TaskRows:
        A, b = np.empty((self.rows, terms.q.shape[0])), np.empty(self.rows)
        self.compute_into(terms, A, b)
        return TaskRows(A, b, self.weight)


def rotation_error(target: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Rotation vector log(R* R^T) in world axes: the angular displacement from R to R*."""
    return pin.log3(target @ rotation.T)


def critical_damping(stiffness: float) -> float:
    return 2.0 * float(np.sqrt(stiffness))


def non_negative(name: str, value) -> float:
    """``value`` as a float, or ValueError when it is not finite and >= 0 (gains, weights)."""
    value = float(value)
    if not (np.isfinite(value) and value >= 0.0):
        raise BadInputError(f"{name} = {value} must be a finite number >= 0")
    return value


def finite_array(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape``, or ValueError (wrong shape or not finite)."""
    array = np.asarray(value, dtype=float)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise BadInputError(f"{name} must be {shape} finite values, got {value!r}")
    return array
