"""Benchmark rows of the impact-aware QP controller (``controller_rows``).

- controller.cycle: microseconds per ``step`` in a kinematic closed loop (q, dq <- q_cmd,
  dq_cmd) approaching the default wall faster than the posture allows, every constraint on,
  the impact-aware ones active (goals: median <= 100 us, p99 <= 250 us);
- peer.pink.cycle: the same robot in pink's ``solve_ik`` (frame task + posture task +
  configuration and velocity limits, velocity level, proxqp), measured in the same run;
- controller.solvers.<backend>: the controller.cycle loop with each available QP backend.
"""

from __future__ import annotations

import time

import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.postures import POSTURES, Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.qp import available_backends
from .base import timing_row

CYCLES = 3000
RESTART_EVERY = 500  # cycles; the loop restarts at the posture before reaching the wall
WALL_GAP = 0.10  # m between the tool tip and the wall at the start


def _approach_setup(robot: PandaModel, solver: str):
    posture = POSTURES["elbow_up"]
    normal = posture.surface.normal
    surface = Surface(robot.contact_point(posture.q) - WALL_GAP * normal, normal)
    controller = build_controller(ControllerConfig.approach(surface, speed=0.5, solver=solver), robot)
    return controller, posture.q


def controller_cycle_samples(robot: PandaModel, solver: str = "proxqp", cycles: int = CYCLES) -> np.ndarray:
    """Seconds per ``step`` of the closed approach loop."""
    controller, q0 = _approach_setup(robot, solver)
    samples = np.empty(cycles)
    q, dq = q0, np.zeros(7)
    for k in range(cycles):
        if k % RESTART_EVERY == 0:
            q, dq = q0, np.zeros(7)
            controller.reset(q, dq)
        start = time.perf_counter()
        command = controller.step(q, dq)
        samples[k] = time.perf_counter() - start
        q, dq = command.q_cmd, command.dq_cmd
    return samples


def pink_cycle_samples(robot: PandaModel, cycles: int = CYCLES) -> np.ndarray:
    """Seconds per cycle of pink: frame task + posture task + limits, solve_ik with proxqp."""
    import pink
    from pink.tasks import FrameTask, PostureTask

    q0 = POSTURES["elbow_up"].q
    configuration = pink.Configuration(robot.model, robot.model.createData(), q0)
    frame_task = FrameTask("impact_tip", position_cost=1.0, orientation_cost=1.0)
    posture_task = PostureTask(cost=1e-2)
    target = configuration.get_transform_frame_to_world("impact_tip").copy()
    target.translation[0] += WALL_GAP
    frame_task.set_target(target)
    posture_task.set_target(q0)
    tasks = [frame_task, posture_task]
    dt = 0.001
    samples = np.empty(cycles)
    for k in range(cycles):
        if k % RESTART_EVERY == 0:
            configuration.update(q0)
        start = time.perf_counter()
        velocity = pink.solve_ik(configuration, tasks, dt, solver="proxqp", safety_break=False)
        configuration.integrate_inplace(velocity, dt)
        samples[k] = time.perf_counter() - start
    return samples


def controller_rows() -> list[dict]:
    robot = PandaModel()
    controller_cycle_samples(robot, cycles=300)  # warm-up
    rows = [timing_row("controller.cycle", "us", controller_cycle_samples(robot), 1e6)]
    rows.append(timing_row("peer.pink.cycle", "us", pink_cycle_samples(robot), 1e6))
    for backend in available_backends():
        name = "controller.solvers." + backend.replace("qpsolvers:", "qpsolvers_")
        rows.append(timing_row(name, "us", controller_cycle_samples(robot, backend, cycles=1000), 1e6))
    return rows

