"""What the robot's sensors make of the true joint velocities and torques (``apply_sensor``).

The sensor keys of ``sim.plant.PlantParameters`` act on a log after the simulation, never on the
physics: a dataset generated with them holds what a faulty sensor would have logged, and the
diagnosis's sensor causes apply them to a replay's output without simulating again.

- ``sensor_velocity_filter`` tau (s): dq is a first-order low-pass estimate of the true
  velocity (libfranka's ``dq`` is one), y_k = y_(k-1) + a (x_k - y_(k-1)), a = T / (tau + T),
  T the control period, y_0 = x_0;
- ``sensor_delay`` d (control periods, fractional): dq and tau are logged d samples late,
  x(t - d T) by linear interpolation between samples, the first sample held before the log;
- ``sensor_velocity_scale`` s and ``sensor_joint_velocity_scale`` s_j: the logged dq of joint j
  is s s_j times the (filtered, delayed) velocity (``velocity_scales``);
- ``sensor_torque_offset`` b (N m per joint): the logged tau is the delayed torque plus b;
- ``sensor_velocity_step`` q_j (rad/s per joint, 0: none): the logged dq of joint j is
  q_j round(dq_j / q_j), an encoder-based velocity, rounded after the encoder noise
  (``quantised_velocity``, which ``sim.generation`` applies once it has added the noise;
  ``apply_sensor`` leaves it out, so a replay is never rounded).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.measured.trial_log import TrialLog


def delayed(x: np.ndarray, samples: float) -> np.ndarray:
    """x (n, m) read ``samples`` samples late by linear interpolation (the first sample held);
    a negative ``samples`` reads ahead (the last sample held)."""
    if samples == 0.0 or len(x) == 0:
        return x
    position = np.clip(np.arange(len(x)) - samples, 0.0, len(x) - 1)
    lower = np.floor(position).astype(int)
    upper = np.minimum(lower + 1, len(x) - 1)
    fraction = (position - lower)[:, None]
    return (1.0 - fraction) * x[lower] + fraction * x[upper]


def low_pass(x: np.ndarray, time_constant: float, period: float) -> np.ndarray:
    """The first-order low-pass filter of the module docstring over the rows of x."""
    if time_constant == 0.0 or len(x) == 0:
        return x
    a = period / (time_constant + period)
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        y[k] = y[k - 1] + a * (x[k] - y[k - 1])
    return y


def has_sensor_effect(plant) -> bool:
    """Whether ``plant`` sets any sensor key away from a perfect sensor."""
    return (
        plant.sensor_delay != 0.0
        or plant.sensor_velocity_scale != 1.0
        or plant.sensor_velocity_filter != 0.0
        or any(plant.sensor_torque_offset)
        or any(s != 1.0 for s in plant.sensor_joint_velocity_scale)
    )


def velocity_scales(plant, joints: int) -> np.ndarray:
    """Logged dq / true dq of each of the ``joints`` joints: the global scale times the joint's
    own (module docstring)."""
    return plant.sensor_velocity_scale * np.asarray(plant.for_joints(joints).sensor_joint_velocity_scale, float)


def apply_sensor(log: TrialLog, plant, period: float) -> TrialLog:
    """The log as the sensors of ``plant`` would have logged it (module docstring); ``period``
    is the control period (s)."""
    if not has_sensor_effect(plant):
        return log
    joints = np.shape(log.dq)[1]
    dq = low_pass(np.asarray(log.dq, float), plant.sensor_velocity_filter, period)
    dq = velocity_scales(plant, joints) * delayed(dq, plant.sensor_delay)
    offset = np.asarray(plant.for_joints(joints).sensor_torque_offset)
    tau = delayed(np.asarray(log.tau, float), plant.sensor_delay) + offset
    return replace(log, dq=dq, tau=tau)


def quantised_velocity(dq: np.ndarray, plant, joints: int) -> np.ndarray:
    """dq (samples x ``joints``) as an encoder of ``plant.sensor_velocity_step`` logs it: each
    joint's rounded to a multiple of its step (module docstring); a joint of step 0 unchanged."""
    steps = np.asarray(plant.for_joints(joints).sensor_velocity_step, float)
    if not np.any(steps > 0.0):
        return dq
    safe = np.where(steps > 0.0, steps, 1.0)
    return np.where(steps > 0.0, safe * np.round(dq / safe), dq)
