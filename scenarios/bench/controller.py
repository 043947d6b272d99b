"""Benchmark rows of the impact-aware QP controller (``controller_rows``).

- controller.cycle: microseconds per ``step`` in a kinematic closed loop (q, dq <- q_cmd,
  dq_cmd) approaching the default wall faster than the posture allows, every constraint on,
  the impact-aware ones active (goals: median <= 100 us, p99 <= 250 us), on the Panda;
- floor.cycle: the floor of that cycle at the same states: the Pinocchio algorithms of its model
  terms (``RobotModel.pinocchio_pass``: an arm's ``computeAllTerms`` and contact placement) and a
  bare ``daqp.solve`` of the controller's own QP (the same H, g, C and stacked bounds, recorded
  along the loop);
- controller.cycle.friction4: the same loop with the robust friction rows of a 4-edge pyramid
  (mu = ``BENCH_FRICTION``; docs/frictional-impacts.md); controller.cycle.robust: the same loop
  with the robust three-model impact rows (crb, gm and classical at once);
- peer.pink.cycle: the same robot in pink's ``solve_ik`` (frame task + posture task +
  configuration and velocity limits, velocity level); peer.mink.cycle: mink on the MuJoCo model
  of our scene (frame task on the tool centre body + posture task + configuration and velocity
  limits); each on its fastest solver in this run (``fastest_solver``: every installed one of
  ``PEER_SOLVERS`` timed on a short block first);
  all of these timed in alternating blocks in one process (``cycle_and_floor_rows``, with
  ``base.alternating_blocks``), with the ratios controller.cycle/floor.cycle,
  controller.cycle/peer.pink.cycle, controller.cycle/peer.mink.cycle,
  controller.cycle.friction4/controller.cycle (goal <= 1.3) and
  controller.cycle.robust/controller.cycle, block by block;
  controller.cycle.fr3 and controller.cycle.ur5 the same loop on the FR3 and on the UR5 (six
  joints, from its description file only), all with the impact tip;
- peer.tsid.cycle: TSID (compiled C++), or a row with a note when TSID is not installable;
- controller.fallback_cycle: microseconds per ``step`` on random infeasible states (too fast
  towards the wall with the impact constraints always on; goal: p99 <= 2x controller.cycle p99);
- controller.stage.<terms|rows|solve|check>: one cycle split into its stages, on
  the states of the controller.cycle loop;
- controller.solvers.<backend>: the controller.cycle loop with each available QP backend, with
  ``.fallbacks`` (fallback cycles in that loop) and ``.speed_ratio`` (asked for 2 m/s at a fixed
  posture, the commanded contact speed it settles at over the crb closed-form maximum speed;
  1 means the QP reaches the closed form): the table the default solver is chosen from.

The standing G1's rows are ``scenarios.bench.whole_body``'s.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import daqp
import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.sim.scene import build_scene
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.controller.model.tool_postures import tool_posture
from impactqp.controller.qp import available_backends
from impactqp.controller.model.max_speed import Setting, approach_direction, closed_form_max_speed

from .base import ALTERNATING_BLOCKS, alternating_blocks, blocks_row, missing_row, ratio_row, timing_row

CYCLES = 3000
RESTART_EVERY = 500  # cycles; the loop restarts at the posture before reaching the wall
WALL_GAP = 0.10  # m between the tool tip and the wall at the start
BENCH_FRICTION = 0.3  # mu of controller.cycle.friction4's rows


def _approach_setup(robot: PandaModel, solver: str | None = None, friction: float = 0.0, jump_model: str = "crb"):
    """The benchmark's approach controller (the configuration's default solver when None; the
    robust friction rows of mu = ``friction`` when > 0; the impact rows of ``jump_model``), at
    the robot's default posture for its tool."""
    posture = tool_posture(robot, robot.description.default_posture)
    normal = posture.surface.normal
    surface = Surface(robot.contact_point(posture.q) - WALL_GAP * normal, normal)
    config = ControllerConfig.approach(surface, speed=0.5, friction=friction, jump_model=jump_model)
    if solver is not None:
        config = replace(config, solver=solver)
    return build_controller(config, robot), posture.q


def controller_cycle_samples(robot: PandaModel, solver: str | None = None, cycles: int = CYCLES) -> np.ndarray:
    """Seconds per ``step`` of the closed approach loop."""
    return _approach_loop(robot, solver, cycles)[0]


def _approach_loop(robot: PandaModel, solver: str | None, cycles: int) -> tuple[np.ndarray, int]:
    """Seconds per ``step`` of the closed approach loop, and its number of fallbacks."""
    controller, q0 = _approach_setup(robot, solver)
    return ClosedLoop(controller, q0, robot.nv).run(cycles)


class ClosedLoop:
    """The kinematic closed loop of a controller (q, v <- q_cmd, v_cmd), restarted at rest at
    ``q0`` every RESTART_EVERY cycles (any controller whose command has ``q_cmd``, ``dq_cmd`` and
    ``is_fallback``); each ``run`` goes on from where the last one stopped."""

    def __init__(self, controller, q0: np.ndarray, nv: int):
        self.controller, self.q0, self.nv = controller, q0, nv
        self.q, self.v, self.cycle = q0, np.zeros(nv), 0

    def run(self, cycles: int, record: list | None = None) -> tuple[np.ndarray, int]:
        """Seconds per ``step`` of the next ``cycles`` cycles and their number of fallback
        commands; with ``record``, each cycle's (q, v, the controller's QP) appended to it."""
        controller = self.controller
        samples = np.empty(cycles)
        fallbacks = 0
        for k in range(cycles):
            if self.cycle % RESTART_EVERY == 0:
                self.q, self.v = self.q0, np.zeros(self.nv)
                controller.reset(self.q, self.v)
            start = time.perf_counter()
            command = controller.step(self.q, self.v)
            samples[k] = time.perf_counter() - start
            if record is not None:
                record.append((self.q, self.v, controller.problem.copy()))
            fallbacks += command.is_fallback
            self.q, self.v, self.cycle = command.q_cmd, command.dq_cmd, self.cycle + 1
        return samples, fallbacks


class CycleFloor:
    """The floor of a controller's cycle at recorded states (``ClosedLoop.run``'s ``record``): the
    Pinocchio algorithms of the robot's model terms (``pinocchio_pass``, on a data of its own) and
    one bare ``daqp.solve`` of the controller's QP, the same H, g, C and stacked bounds; each
    ``run`` times the next states, in a ring."""

    def __init__(self, robot: RobotModel, states: list):
        self.robot, self.data, self.states, self.next = robot, robot.model.createData(), states, 0
        rows, n = states[0][2].C.shape
        self.sense = np.zeros(n + rows, dtype=np.int32)

    def run(self, cycles: int) -> np.ndarray:
        """Seconds per floor cycle of the next ``cycles`` recorded states."""
        samples = np.empty(cycles)
        dynamics, data, sense = self.robot.pinocchio_pass, self.data, self.sense
        for k in range(cycles):
            q, v, problem = self.states[self.next]
            self.next = (self.next + 1) % len(self.states)
            start = time.perf_counter()
            dynamics(data, q, v)
            sense.fill(0)
            daqp.solve(problem.H, problem.g, problem.C, problem.upper, problem.lower, sense)
            samples[k] = time.perf_counter() - start
        return samples


def cycle_and_floor_rows(
    name: str,
    floor: str,
    robot: RobotModel,
    setup: Callable[[], tuple],
    variants: dict[str, Callable[[], tuple]] | None = None,
    peers: dict[str, tuple[Callable[[int], np.ndarray], str]] | None = None,
) -> list[dict]:
    """The rows ``name`` (us per ``step`` of the closed loop of ``setup()`` = (controller, q0)),
    ``floor`` (``CycleFloor`` at the states of the same loop, recorded by a twin controller) and
    their ratio, timed in alternating blocks of CYCLES // ALTERNATING_BLOCKS cycles after a
    warm-up of each; each of ``variants`` (row name: its setup) is a closed loop timed in the same
    blocks, with its ratio to ``name``; each of ``peers`` (row name: (its loop's ``run``, seconds
    per cycle of the next cycles; the row's note)) too, with the ratio of ``name`` to it."""
    variants, peers = variants or {}, peers or {}
    states: list = []
    ClosedLoop(*setup(), robot.nv).run(CYCLES, states)
    loop, cycle_floor = ClosedLoop(*setup(), robot.nv), CycleFloor(robot, states)
    others = {variant: ClosedLoop(*make(), robot.nv) for variant, make in variants.items()}
    runs = {name: lambda cycles: loop.run(cycles)[0], floor: cycle_floor.run}
    runs |= {variant: (lambda cycles, other=other: other.run(cycles)[0]) for variant, other in others.items()}
    runs |= {peer: run for peer, (run, _) in peers.items()}
    for run in runs.values():
        run(300)  # warm-up (numba kernels, caches)
    block = CYCLES // ALTERNATING_BLOCKS
    blocks = alternating_blocks({row: (lambda run=run: run(block)) for row, run in runs.items()})
    rows = [blocks_row(name, "us", blocks[name], 1e6), blocks_row(floor, "us", blocks[floor], 1e6), ratio_row(name, floor, blocks)]
    for variant in variants:
        rows += [blocks_row(variant, "us", blocks[variant], 1e6), ratio_row(variant, name, blocks)]
    for peer, (_, note) in peers.items():
        rows += [{**blocks_row(peer, "us", blocks[peer], 1e6), "note": note}, ratio_row(name, peer, blocks)]
    return rows


def settled_speed_ratio(robot: PandaModel, solver: str) -> float:
    """Asked for 2 m/s at elbow_up (posture held fixed, the wall 5 cm ahead, the impact rows
    always on), the commanded contact speed after 0.8 s over the crb closed-form maximum."""
    posture = tool_posture(robot, "elbow_up")
    q, normal = posture.q, posture.surface.normal
    surface = Surface(robot.contact_point(q) - 0.05 * normal, normal)
    config = ControllerConfig.approach(surface, speed=2.0, solver=solver, always_active=True, posture_weight=0.0)
    controller = build_controller(config, robot)
    dq = np.zeros(robot.nv)
    for _ in range(800):
        dq = controller.step(q, dq).dq_cmd
    terms = robot.terms(q)
    closed_form = closed_form_max_speed(robot, terms, normal, Setting("crb"))
    return float(-normal @ (terms.J @ dq)) / closed_form.speed


PEER_SOLVERS = ("daqp", "proxqp", "quadprog")
"""The QP backends a peer (pink, mink: through qpsolvers) is timed with; its row uses the fastest."""
SOLVER_TRIAL_CYCLES = 300


def fastest_solver(samples_of: Callable[[str, int], np.ndarray]) -> tuple[str, str]:
    """A peer's fastest solver in this run, and the note that says so: each of ``PEER_SOLVERS``
    installed here times a short block (``samples_of(solver, cycles)``: seconds per cycle), the
    fastest median wins."""
    import qpsolvers

    candidates = [solver for solver in PEER_SOLVERS if solver in qpsolvers.available_solvers]
    trial = {solver: float(np.median(samples_of(solver, SOLVER_TRIAL_CYCLES))) for solver in candidates}
    best = min(trial, key=trial.get)
    timed = ", ".join(f"{solver} {1e6 * seconds:.1f} us" for solver, seconds in trial.items())
    return best, f"solver {best}: the fastest in this run ({timed})"


def fastest_solver_row(name: str, samples_of: Callable[[str, int], np.ndarray], cycles: int = CYCLES) -> dict:
    """The row of a peer on its fastest solver in this run (``fastest_solver``), timed over
    ``cycles``; the row's note names the solver."""
    best, note = fastest_solver(samples_of)
    return {**timing_row(name, "us", samples_of(best, cycles), 1e6), "note": note}


def pink_cycle_loop(robot: PandaModel, solver: str) -> PeerLoop:
    """pink's loop on the arm: frame task + posture task + limits, solve_ik with ``solver``."""
    return pink_loop(robot.model, PANDA.postures["elbow_up"].q, "impact_tip", solver)


def pink_loop_samples(model, q0: np.ndarray, frame: str, solver: str, cycles: int) -> np.ndarray:
    """Seconds per cycle of ``cycles`` cycles of a new ``pink_loop``."""
    return pink_loop(model, q0, frame, solver).run(cycles)


def pink_loop(model, q0: np.ndarray, frame: str, solver: str) -> PeerLoop:
    """pink's ``solve_ik`` loop (frame task on ``frame``, its target WALL_GAP ahead along x, +
    posture task + pink's limits) from q0."""
    import pink  # optional peer (the bench extra): loaded only for its rows
    from pink.tasks import FrameTask, PostureTask

    configuration = pink.Configuration(model, model.createData(), q0)
    frame_task = FrameTask(frame, position_cost=1.0, orientation_cost=1.0)
    posture_task = PostureTask(cost=1e-2)
    target = configuration.get_transform_frame_to_world(frame).copy()
    target.translation[0] += WALL_GAP
    frame_task.set_target(target)
    posture_task.set_target(q0)
    tasks = [frame_task, posture_task]
    return PeerLoop(configuration, q0, lambda dt: pink.solve_ik(configuration, tasks, dt, solver=solver, safety_break=False))


class PeerLoop:
    """A peer's differential-IK loop (pink's and mink's share its shape): ``solve(dt)`` the
    velocity, integrated into ``configuration``, restarted at q0 every RESTART_EVERY cycles;
    each ``run`` goes on from where the last one stopped."""

    DT = 0.001

    def __init__(self, configuration, q0: np.ndarray, solve: Callable):
        self.configuration, self.q0, self.solve, self.cycle = configuration, q0, solve, 0

    def run(self, cycles: int) -> np.ndarray:
        """Seconds per cycle of the next ``cycles`` cycles."""
        configuration, solve, dt = self.configuration, self.solve, self.DT
        samples = np.empty(cycles)
        for k in range(cycles):
            if self.cycle % RESTART_EVERY == 0:
                configuration.update(self.q0)
            start = time.perf_counter()
            configuration.integrate_inplace(solve(dt), dt)
            samples[k] = time.perf_counter() - start
            self.cycle += 1
        return samples


def mink_cycle_loop(solver: str) -> PeerLoop:
    """mink's loop on the MuJoCo model of our scene: frame task + posture task + configuration
    and velocity limits, solve_ik with ``solver``."""
    import mink  # optional peer (the bench extra): loaded only for its row

    model = build_scene().model
    q0 = PANDA.postures["elbow_up"].q
    configuration = mink.Configuration(model, q0)
    frame_task = mink.FrameTask("panda_hand_tcp", "body", position_cost=1.0, orientation_cost=1.0)
    posture_task = mink.PostureTask(model, cost=1e-2)
    target = configuration.get_transform_frame_to_world("panda_hand_tcp", "body")
    frame_task.set_target(mink.SE3.from_translation(np.array([WALL_GAP, 0.0, 0.0])) @ target)
    posture_task.set_target(q0)
    tasks = [frame_task, posture_task]
    limits = [
        mink.ConfigurationLimit(model),
        mink.VelocityLimit(model, {model.joint(i).name: 2.0 for i in range(model.njnt)}),
    ]
    return PeerLoop(configuration, q0, lambda dt: mink.solve_ik(configuration, tasks, dt, solver, limits=limits))


def arm_peers(robot: PandaModel) -> tuple[dict[str, tuple[Callable[[int], np.ndarray], str]], list[dict]]:
    """pink's and mink's loops on their fastest solver (``cycle_and_floor_rows``' ``peers``),
    and a row with a note for a peer that is not installed."""
    makers = {"peer.pink.cycle": lambda solver: pink_cycle_loop(robot, solver), "peer.mink.cycle": mink_cycle_loop}
    peers, missing = {}, []
    for name, make in makers.items():
        try:
            best, note = fastest_solver(lambda solver, cycles, make=make: make(solver).run(cycles))
        except ImportError as error:
            missing.append(missing_row(name, "us", f"{name.split('.')[1]} is not installed ({error})"))
            continue
        peers[name] = (make(best).run, note)
    return peers, missing


def fallback_cycle_samples(robot: PandaModel, cycles: int = 1000, seed: int = 0) -> np.ndarray:
    """Seconds per ``step`` on infeasible states: elbow_up approaching a wall 5 cm ahead at a
    random 0.55-0.70 m/s with the impact constraints always on (only the cycles that end
    ``fallback_infeasible`` count)."""
    q = PANDA.postures["elbow_up"].q
    normal = np.array([-1.0, 0.0, 0.0])
    surface = Surface(robot.contact_point(q) - 0.05 * normal, normal)
    config = ControllerConfig.approach(surface, speed=2.0, always_active=True, posture_weight=0.0)
    controller = build_controller(config, robot)
    direction = approach_direction(robot, robot.terms(q), normal)
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
    """Seconds per stage of one cycle on the states of the controller.cycle loop: the stages
    of ``ImpactAwareController.step``, each timed on its own (terms: the model terms refilled;
    rows: the control cycle, the task rows and cost and every bound and row, the compiled cycle
    plan's one call; solve: the QP solver; check: the feasibility check and the active
    constraints)."""
    controller, q0 = _approach_setup(robot)
    stages = {name: np.empty(cycles) for name in ("terms", "rows", "solve", "check")}
    q, dq = q0, np.zeros(robot.nv)
    controller.reset(q, dq)
    terms = robot.terms(q, dq)
    for k in range(cycles):
        t0 = time.perf_counter()
        robot.update_terms(terms, q, dq)
        t1 = time.perf_counter()
        controller._cycle.advance(controller.memory.ddq, controller.ddq_max, controller._jerk_step)
        controller._assemble(terms, controller._cycle)
        t2 = time.perf_counter()
        _, ddq = controller.solver.solve(controller.problem)
        t3 = time.perf_counter()
        if ddq is not None:
            controller._checked(ddq)
            controller._active_constraints()
        t4 = time.perf_counter()
        for name, elapsed in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            stages[name][k] = elapsed
        command = controller.step(q, dq)
        q, dq = command.q_cmd, command.dq_cmd
    return stages


def controller_rows() -> list[dict]:
    robot = PandaModel()
    variants = {
        "controller.cycle.friction4": lambda: _approach_setup(robot, friction=BENCH_FRICTION),
        "controller.cycle.robust": lambda: _approach_setup(robot, jump_model="robust"),
    }
    peers, rows = arm_peers(robot)
    rows += cycle_and_floor_rows("controller.cycle", "floor.cycle", robot, lambda: _approach_setup(robot), variants, peers)
    for name in ("fr3", "ur5"):
        other = RobotModel(name)
        controller_cycle_samples(other, cycles=300)  # warm-up
        rows.append(timing_row(f"controller.cycle.{name}", "us", controller_cycle_samples(other), 1e6))
    rows.append(missing_row(
        "peer.tsid.cycle", "us",
        "TSID cannot be installed beside our Pinocchio: tsid 1.10 needs libtsid 1.10, which PyPI has only as "
        "source (its build needs Eigen3 and a full C++ toolchain set-up), and the newest tsid wheel that "
        "installs (1.7.1) pins pin 3.7, below the pin 4 this project uses",
    ))
    rows.append(timing_row("controller.fallback_cycle", "us", fallback_cycle_samples(robot), 1e6))
    for name, samples in stage_samples(robot).items():
        rows.append(timing_row(f"controller.stage.{name}", "us", samples, 1e6))
    for backend in available_backends():
        name = "controller.solvers." + backend.replace("qpsolvers:", "qpsolvers_")
        samples, fallbacks = _approach_loop(robot, backend, 1000)
        rows.append(timing_row(name, "us", samples, 1e6))
        rows.append({"name": f"{name}.fallbacks", "unit": "count", "median": float(fallbacks), "p99": float(fallbacks)})
        ratio = settled_speed_ratio(robot, backend)
        rows.append({"name": f"{name}.speed_ratio", "unit": "ratio", "median": ratio, "p99": ratio})
    return rows

