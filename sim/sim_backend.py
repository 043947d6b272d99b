"""The ``sim`` backend: the MuJoCo plant (``sim``) behind the robot interface.

One ``write`` gives the plant the command of one period, which it runs as the trial loop does
(``sim.trial_loop.ServoedPlant``): the computed-torque joint servo turns the command into a torque
held over the period, MuJoCo runs its substeps, and the contact force on the tool is logged at
every substep. The period runs at the next ``read`` (or ``stop``, ``force_log``), not inside
``write``: a real robot moves while its controller computes, so the loop's cycle time (``read``
returning to ``write`` returning, its deadline) is the controller's and not the simulated robot's
physics (a standing G1's period, servo and contacts, costs about as much as its controller).
``read`` returns the state at the start of the next period; its ``tau`` is the torque that acted
over the previous period (the last measured joint torque of a robot). Paced, ``read`` then waits
for the wall-clock time t0 + k period, t0 the time of ``start`` (sleep, then spin for the last
``SPIN_TIME``): a plant slower than real time is caught up, never skipped; unpaced, it returns at
once.
"""

from __future__ import annotations

import time

import numpy as np

from impactqp.sim.scene import MujocoScene, to_pinocchio
from impactqp.sim.servo import StandingSupport
from impactqp.sim.trial_loop import ServoedPlant

from impactqp.controller.runtime.interface import RobotInterface, RobotState

SPIN_TIME = 2e-4


class SimRobot(RobotInterface):
    """The simulated robot of ``scene`` started at the Pinocchio state (q0, dq0), stepped one
    period per command; ``standing`` for a floating base held by its contacts (with the servo's
    ``gain``, rad/s; None: the plant's)."""

    def __init__(
        self, scene: MujocoScene, q0: np.ndarray, dq0: np.ndarray, period: float = 1e-3, paced: bool = False,
        standing: StandingSupport | None = None, gain: float | None = None,
    ):
        self.plant = ServoedPlant(scene, period, gain=gain, standing=standing)
        self.plant.reset(np.asarray(q0, float), np.asarray(dq0, float))
        self.plant.prepare()  # before real time
        self.scene = scene
        self.period = float(period)
        self.paced = paced
        self.base_nq, self.base_nv = scene.base_nq, scene.base_nv
        self.tau = scene.data.qfrc_bias[self.base_nv:].copy()
        self.steps = 0
        self._force: list[np.ndarray] = []
        self._start: float | None = None
        self._pending: np.ndarray | None = None  # the command written and not yet run

    def read(self) -> RobotState:
        self._run_pending()
        if self.paced:
            now = time.perf_counter()
            if self._start is None:
                self._start = now
            deadline = self._start + self.steps * self.period
            if deadline - now > SPIN_TIME:
                time.sleep(deadline - now - SPIN_TIME)
            while time.perf_counter() < deadline:
                pass
        data, t = self.scene.data, self.steps * self.period
        if not self.base_nq:
            return RobotState(t, data.qpos.copy(), data.qvel.copy(), self.tau.copy())
        q, v = to_pinocchio(data.qpos, data.qvel, self.base_nq)
        base = np.concatenate([q[: self.base_nq], v[: self.base_nv]])
        return RobotState(t, q[self.base_nq:], v[self.base_nv:], self.tau.copy(), base=base)

    def hold(self, duration: float) -> None:
        """Hold the joints still (zero command) for ``duration`` s before the run; the run's clock
        and its force log start after it."""
        force = np.zeros((self.plant.substeps, 3))
        for _ in range(int(round(duration / self.period))):
            self.tau = self.plant.advance(np.zeros(len(self.tau)), force).copy()

    def start(self) -> None:
        """Start the wall clock of the pacing at this cycle."""
        self._start = time.perf_counter() - self.steps * self.period

    def write(self, dq_cmd: np.ndarray) -> None:
        self._run_pending()
        self._pending = np.array(dq_cmd, dtype=float)

    def stop(self) -> None:
        self._run_pending()

    def _run_pending(self) -> None:
        """The period of the last written command, once (module docstring)."""
        if self._pending is None:
            return
        command, self._pending = self._pending, None
        force = np.zeros((self.plant.substeps, 3))
        self.tau = self.plant.advance(command, force).copy()
        self._force.append(force)
        self.steps += 1

    def force_log(self) -> tuple[np.ndarray, np.ndarray]:
        self._run_pending()
        force = np.concatenate(self._force) if self._force else np.zeros((0, 3))
        return np.arange(len(force)) * self.scene.timestep, force
