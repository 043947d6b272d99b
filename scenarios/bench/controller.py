"""Benchmark rows of the impact-aware QP controller (``controller_rows``).

- controller.cycle: microseconds per ``step`` in a kinematic closed loop (q, dq <- q_cmd,
  dq_cmd) approaching the default wall faster than the posture allows, every constraint on,
  the impact-aware ones active (goals: median <= 100 us, p99 <= 250 us);
- peer.pink.cycle: the same robot in pink's ``solve_ik`` (frame task + posture task +
  configuration and velocity limits, velocity level, proxqp), measured in the same run;
- peer.mink.cycle: mink on the MuJoCo model of our scene (frame task on the tool centre body +
  posture task + configuration and velocity limits, daqp), same loop;
- peer.tsid.cycle: TSID (compiled C++), or a row with a note when TSID is not installable;
- controller.fallback_cycle: microseconds per ``step`` on random infeasible states (too fast
  towards the wall with the impact constraints always on; goal: p99 <= 2x controller.cycle p99);
- controller.stage.<terms|tasks|constraints|solve|check>: one cycle split into its stages, on
  the states of the controller.cycle loop;
- controller.solvers.<backend>: the controller.cycle loop with each available QP backend.
"""

from __future__ import annotations

import time

import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.postures import POSTURES, Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.qp import available_backends
from impactqp.controller.model.max_speed import approach_direction

from .base import missing_row, timing_row

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


def mink_cycle_samples(cycles: int = CYCLES) -> np.ndarray:
    """Seconds per cycle of mink on the MuJoCo model of our scene: frame task + posture task +
    configuration and velocity limits, solve_ik with daqp."""
    import mink

    from impactqp.sim.scene import build_scene

    model = build_scene().model
    q0 = POSTURES["elbow_up"].q
    configuration = mink.Configuration(model, q0)
    frame_task = mink.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    posture_task = mink.PostureTask(model, cost=1e-2)
    target = configuration.get_transform_frame_to_world("panda_hand_tcp", "body")
    frame_task.set_target(mink.SE3.from_translation(np.array([WALL_GAP, 0.0, 0.0])) @ target)
    posture_task.set_target(q0)
    tasks = [frame_task, posture_task]
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, {model.joint(i).name: 2.0 for i in range(7)}),
    ]
    dt = 0.001
    samples = np.empty(cycles)
    for k in range(cycles):
        if k % RESTART_EVERY == 0:
            configuration.update(q0)
        start = time.perf_counter()
        velocity = mink.solve_ik(configuration, tasks, dt, "daqp", limits=limits)
        configuration.integrate_inplace(velocity, dt)
        samples[k] = time.perf_counter() - start
    return samples


def fallback_cycle_samples(robot: PandaModel, cycles: int = 1000, seed: int = 0) -> np.ndarray:
    """Seconds per ``step`` on infeasible states: elbow_up approaching a wall 5 cm ahead at a
    random 0.55-0.70 m/s with the impact constraints always on (only the cycles that end
    ``fallback_infeasible`` count)."""
    q = POSTURES["elbow_up"].q
    normal = np.array([-1.0, 0.0, 0.0])
    surface = Surface(robot.contact_point(q) - 0.05 * normal, normal)
    config = ControllerConfig.approach(surface, speed=2.0, always_active=True, posture_weight=0.0)
    controller = build_controller(config, robot)
    direction = approach_direction(robot.terms(q), normal)
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(20 * cycles):
        if len(samples) == cycles:
            break
        dq = rng.uniform(0.55, 0.70) * direction
        controller.reset(q, dq)
        start = time.perf_counter()
        command = controller.step(q, dq)
        elapsed = time.perf_counter() - start
        if command.status == "fallback_infeasible":
            samples.append(elapsed)
    return np.array(samples)


def stage_samples(robot: PandaModel, cycles: int = 1000) -> dict[str, np.ndarray]:
    """Seconds per stage of one cycle (terms, tasks, constraints, solve, check) on the states
    of the controller.cycle loop, each stage timed on its own."""
    from impactqp.constraints import ControlCycle

    controller, q0 = _approach_setup(robot, "proxqp")
    stages = {name: np.empty(cycles) for name in ("terms", "tasks", "constraints", "solve", "check")}
    q, dq = q0, np.zeros(7)
    controller.reset(q, dq)
    for k in range(cycles):
        t0 = time.perf_counter()
        terms = robot.terms(q, dq)
        t1 = time.perf_counter()
        for task in controller.tasks:
            task.compute(terms)
        t2 = time.perf_counter()
        cycle = ControlCycle.after(controller.memory.ddq, controller.dt, controller.ddq_max, controller.dddq_max)
        for constraint in controller.constraints:
            constraint.compute(terms, cycle)
        t3 = time.perf_counter()
        controller._assemble(terms, cycle)  # the QP data the solver needs (not timed again)
        t4 = time.perf_counter()
        outcome = controller.solver.solve(controller.problem)
        t5 = time.perf_counter()
        controller._acceptable(outcome)
        t6 = time.perf_counter()
        for name, elapsed in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t5 - t4, t6 - t5)):
            stages[name][k] = elapsed
        command = controller.step(q, dq)
        q, dq = command.q_cmd, command.dq_cmd
    return stages


def controller_rows() -> list[dict]:
    robot = PandaModel()
    controller_cycle_samples(robot, cycles=300)  # warm-up
    rows = [timing_row("controller.cycle", "us", controller_cycle_samples(robot), 1e6)]
    rows.append(timing_row("peer.pink.cycle", "us", pink_cycle_samples(robot), 1e6))
    try:
        rows.append(timing_row("peer.mink.cycle", "us", mink_cycle_samples(), 1e6))
    except ImportError as error:
        rows.append(missing_row("peer.mink.cycle", "us", f"mink is not installed ({error})"))
    try:
        import tsid  # noqa: F401
    except ImportError:
        rows.append(missing_row(
            "peer.tsid.cycle", "us",
            "TSID not installable: PyPI has no libtsid wheel for this platform and its source build fails",
        ))
    else:
        rows.append(missing_row("peer.tsid.cycle", "us", "TSID is installed but its loop is not written yet"))
    rows.append(timing_row("controller.fallback_cycle", "us", fallback_cycle_samples(robot), 1e6))
    for name, samples in stage_samples(robot).items():
        rows.append(timing_row(f"controller.stage.{name}", "us", samples, 1e6))
    for backend in available_backends():
        name = "controller.solvers." + backend.replace("qpsolvers:", "qpsolvers_")
        rows.append(timing_row(name, "us", controller_cycle_samples(robot, backend, cycles=1000), 1e6))
    return rows

