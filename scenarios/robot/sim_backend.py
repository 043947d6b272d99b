"""The ``sim`` backend: the MuJoCo plant (``sim``) behind the robot interface.

One ``write`` advances the plant by one period exactly as ``sim.runner.run_trial`` does: the
computed-torque joint servo turns the command into a torque held over the period, MuJoCo runs its
substeps, and the contact force on the tool is logged at every substep. ``read`` returns the state
at the start of the next period; its ``tau`` is the torque that acted over the previous period
(the last measured joint torque of a robot). Paced, ``read`` waits for the wall-clock time
t0 + k period (sleep, then spin for the last ``SPIN_TIME``); unpaced, it returns at once.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from impactqp.sim.runner import ComputedTorqueServo
from impactqp.sim.scene import Scene

from .interface import RobotInterface, RobotState

SPIN_TIME = 2e-4


class SimRobot(RobotInterface):
    """The simulated Panda of ``scene`` started at (q0, dq0), stepped one period per command."""

    has_contact_truth = True

    def __init__(self, scene: Scene, q0: np.ndarray, dq0: np.ndarray, period: float = 1e-3, paced: bool = False):
        substeps = int(round(period / scene.timestep))
        if substeps < 1 or abs(substeps * scene.timestep - period) > 1e-9:
            raise ValueError(f"period {period} s is not a whole number of timesteps ({scene.timestep} s)")
        self.scene = scene
        self.period = float(period)
        self.substeps = substeps
        self.paced = paced
        scene.set_state(np.asarray(q0, float), np.asarray(dq0, float))
        self.servo = ComputedTorqueServo(scene, scene.plant.servo_gain)
        self.servo.reset(q0, dq0)
        self.tau = scene.data.qfrc_bias.copy()
        self.steps = 0
        self._force: list[np.ndarray] = []
        self._contact_force = np.zeros(6)
        self._start: float | None = None

    def read(self) -> RobotState:
        if self.paced:
            now = time.perf_counter()
            if self._start is None:
                self._start = now
            deadline = self._start + self.steps * self.period
            if deadline - now > SPIN_TIME:
                time.sleep(deadline - now - SPIN_TIME)
            while time.perf_counter() < deadline:
                pass
        data = self.scene.data
        return RobotState(self.steps * self.period, data.qpos.copy(), data.qvel.copy(), self.tau.copy())

    def write(self, dq_cmd: np.ndarray) -> None:
        model, data, scene = self.scene.model, self.scene.data, self.scene
        mujoco.mj_step1(model, data)
        self.tau = self.servo.torque(np.asarray(dq_cmd, float), self.period).copy()
        data.qfrc_applied[:] = self.tau
        mujoco.mj_step2(model, data)
        force = np.zeros((self.substeps, 3))
        for i in range(self.substeps):
            if i > 0:
                mujoco.mj_step(model, data)
            for c in range(data.ncon):
                mujoco.mj_contactForce(model, data, c, self._contact_force)
                contact = data.contact[c]
                on_geom2 = contact.frame.reshape(3, 3).T @ self._contact_force[:3]
                force[i] += on_geom2 if contact.geom2 == scene.tool_geom else -on_geom2
        self._force.append(force)
        self.steps += 1

    def force_log(self) -> tuple[np.ndarray, np.ndarray]:
        force = np.concatenate(self._force) if self._force else np.zeros((0, 3))
        return np.arange(len(force)) * self.scene.timestep, force
