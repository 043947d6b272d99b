"""The arrays of one impact trial, simulated or measured: the unit that the dataset format stores
and the impact measurement reads (``docs/dataset.md``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class TrialLog:
    """Arrays of one trial.

    Control rate (N samples, sample k at t[k], state measured at the start of period k):
    ``t`` (N,), ``q``, ``dq``, ``tau`` (servo torque applied over period k), ``dq_cmd`` (N, joints).
    Physics rate (K samples): ``force_t`` (K,), ``force`` (K, 3), the total contact force on the
    robot (world frame, N) acting over [force_t[i], force_t[i] + timestep). Empty force arrays
    mean that the log holds no force measurement (e.g. a robot log without a sensor).
    ``wall_time`` is the time the simulation took (s), 0 for a log that was not simulated.
    ``base`` (N, 13): a floating base's state per control sample (position, quaternion x, y, z,
    w, twist in the base frame: ``controller.measured.dataset_robot``), empty for a fixed-base arm.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    dq_cmd: np.ndarray
    force_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    force: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    wall_time: float = 0.0
    base: np.ndarray = field(default_factory=lambda: np.zeros((0, 13)))

    def __len__(self) -> int:
        return len(self.t)

    @property
    def has_force(self) -> bool:
        return len(self.force_t) > 0

    def truncated(self, t_end: float) -> "TrialLog":
        """The log up to the first control sample at or after ``t_end`` (excluded), with the
        force samples of the kept control periods."""
        k = int(np.searchsorted(self.t, t_end))
        t_cut = self.t[k] if k < len(self.t) else np.inf
        i = int(np.searchsorted(self.force_t, t_cut - 1e-12))
        return TrialLog(
            self.t[:k], self.q[:k], self.dq[:k], self.tau[:k], self.dq_cmd[:k],
            self.force_t[:i], self.force[:i], self.wall_time, self.base[:k],
        )

    @property
    def control_period(self) -> float:
        return float(np.median(np.diff(self.t)))
