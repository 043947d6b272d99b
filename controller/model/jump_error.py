"""How far a predicted joint-velocity jump is from a measured one (the paper's Sec. VII-A).

The absolute error per joint, eq. (25): e_i = ddq*_i - ddq°_i, with ddq* the predicted and ddq°
the measured jump of joint i; the average error over the D joints, eq. (26):
(1/D) sum_i |ddq*_i - ddq°_i|. Both act on the last axis, so a batch of trials is one call.
"""

from __future__ import annotations

import numpy as np


def prediction_error(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Absolute prediction error e = ddq* - ddq°, eq. (25), per joint (last axis)."""
    return np.asarray(predicted) - np.asarray(measured)


def average_prediction_error(predicted: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Average prediction error (1/D) sum_i |ddq*_i - ddq°_i|, eq. (26), over the last axis."""
    return np.mean(np.abs(prediction_error(predicted, measured)), axis=-1)
