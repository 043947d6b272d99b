"""Benchmark rows of the standing G1's whole-body QP (``rows``), beside the arm's
(``scenarios.bench.controller``), and pink's version of the same problem.

- controller.cycle.g1: microseconds per ``ImpactAwareController.step`` of the standing G1 (parallel
  stance, the right hand approaching a wall 10 cm ahead at 0.5 m/s, every task and constraint on,
  model terms once per cycle, daqp), the arm's closed loop (``controller.ClosedLoop``); .proxqp the
  same loop with proxqp updated and warm-started every cycle; floor.cycle.g1 and
  ``controller.cycle.g1/floor.cycle.g1`` its floor and ratio, as the arm's floor.cycle;
- peer.pink.cycle.g1: pink's ``solve_ik`` on the same G1 model and the same tasks (the hand's
  contact frame, the centre of mass, the torso's orientation, the posture), both feet held as
  equality constraints (pink's ``constraints``: frame tasks kept exactly), pink's configuration and
  velocity limits, the same loop on pink's fastest backend; pink is a velocity-level IK, so it has
  no impact, capture or foot-wrench rows, and no acceleration or jerk limits. The row's note gives
  both problems' sizes (unknowns, equality and inequality rows, bounds); it is timed in the same
  alternating blocks as controller.cycle.g1 and its floor, and
  ``controller.cycle.g1/peer.pink.cycle.g1`` is the ratio of the blocks' medians (goal <= 0.7).
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel

from .base import missing_row, timing_row
from .controller import CYCLES, WALL_GAP, ClosedLoop, PeerLoop, cycle_and_floor_rows, fastest_solver

G1_STANCE = "parallel"
PINK_WEIGHTS = {"hand": 1.0, "com": 10.0, "torso": 10.0, "posture": 1e-4}
"""pink's task costs: the whole-body QP's weights (docs/whole-body-qp.md), the hand's position and
orientation at 1."""


def g1_setup(robot: RobotModel, solver: str = "daqp") -> tuple:
    """The G1's approach controller and its stance q0: the right hand 10 cm before a wall ahead
    at 0.5 m/s."""
    q0 = stance_posture(robot, robot.description.stances[G1_STANCE])
    normal = np.array([-1.0, 0.0, 0.0])
    surface = Surface(robot.terms(q0).contact_point - WALL_GAP * normal, normal)
    config = ControllerConfig.approach(surface, 0.5, robot=robot.description.name, solver=solver)
    return build_controller(config, robot, q0), q0


def g1_cycle_samples(robot: RobotModel, solver: str = "daqp", cycles: int = CYCLES) -> np.ndarray:
    """Seconds per ``step`` of the G1's closed approach loop (q, v <- q_cmd, v_cmd), restarted at
    the stance every RESTART_EVERY cycles."""
    return ClosedLoop(*g1_setup(robot, solver), robot.nv).run(cycles)[0]


class PinkWholeBody:
    """pink's version of the whole-body problem on the G1 (module docstring): its configuration
    at the stance, its tasks, the feet as equality constraints and its limits."""

    def __init__(self, robot: RobotModel):
        import pink  # optional peer (the bench extra): loaded only for its rows
        from pink.tasks import ComTask, FrameTask, PostureTask

        self.q0 = stance_posture(robot, robot.description.stances[G1_STANCE])
        self.configuration = pink.Configuration(robot.model, robot.model.createData(), self.q0)
        hand = FrameTask(robot.model.frames[robot.contact_frame_id].name, position_cost=PINK_WEIGHTS["hand"],
                         orientation_cost=PINK_WEIGHTS["hand"])
        target = self.configuration.get_transform_frame_to_world(hand.frame).copy()
        target.translation[0] += WALL_GAP
        hand.set_target(target)
        com = ComTask(cost=PINK_WEIGHTS["com"])
        com.set_target_from_configuration(self.configuration)
        torso = FrameTask(robot.description.frames["torso"], position_cost=0.0, orientation_cost=PINK_WEIGHTS["torso"])
        posture = PostureTask(cost=PINK_WEIGHTS["posture"])
        self.feet = [FrameTask(frame, position_cost=1.0, orientation_cost=1.0) for frame in robot.held_frames]
        for task in (torso, posture, *self.feet):
            task.set_target_from_configuration(self.configuration)
        self.tasks = [hand, com, torso, posture]

    def solve(self, dt: float, solver: str) -> np.ndarray:
        import pink

        return pink.solve_ik(self.configuration, self.tasks, dt, solver=solver, constraints=self.feet, safety_break=False)

    def sizes(self) -> str:
        """Its QP's size at the stance: unknowns, equality rows, inequality rows."""
        import pink

        self.configuration.update(self.q0)
        problem = pink.build_ik(self.configuration, self.tasks, 0.001, constraints=self.feet)
        return f"pink: {problem.P.shape[0]} unknowns, {problem.A.shape[0]} equality rows, {problem.G.shape[0]} inequality rows"


def pink_g1_loop(pink_problem: PinkWholeBody, solver: str) -> PeerLoop:
    """pink's whole-body loop with ``solver``, restarted at the stance."""
    return PeerLoop(pink_problem.configuration, pink_problem.q0, lambda dt: pink_problem.solve(dt, solver))


def qp_sizes(controller) -> str:
    """The whole-body QP's size: unknowns, equality rows, other rows and bounds on the unknowns."""
    problem = controller.problem
    equalities = int(np.sum(problem.l == problem.u))
    n = problem.H.shape[0]
    return f"ours: {n} unknowns, {equalities} equality rows, {len(problem.l) - equalities} inequality rows, {n} bounds"


def rows() -> list[dict]:
    """controller.cycle.g1 with its floor, pink's row on the same problem (its note: both
    problems' sizes) and their ratios, timed in alternating blocks; the proxqp twin."""
    g1 = RobotModel("g1")
    peers, missing = {}, []
    try:
        pink_problem = PinkWholeBody(g1)
    except ImportError as error:
        missing.append(missing_row("peer.pink.cycle.g1", "us", f"pink is not installed ({error})"))
    else:
        controller, q0 = g1_setup(g1)
        controller.reset(q0, np.zeros(g1.nv))
        controller.step(q0, np.zeros(g1.nv))
        best, note = fastest_solver(lambda solver, cycles: pink_g1_loop(pink_problem, solver).run(cycles))
        peers["peer.pink.cycle.g1"] = (pink_g1_loop(pink_problem, best).run, f"{note}; {qp_sizes(controller)}; {pink_problem.sizes()}")
    return [
        *cycle_and_floor_rows("controller.cycle.g1", "floor.cycle.g1", g1, lambda: g1_setup(g1), peers=peers),
        timing_row("controller.cycle.g1.proxqp", "us", g1_cycle_samples(g1, "proxqp"), 1e6),
        *missing,
    ]
