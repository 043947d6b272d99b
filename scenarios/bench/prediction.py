"""Benchmark rows of the jump predictors, all timed in alternating blocks in one run
(``base.alternating_blocks``): ``predict.crb.single`` (one full CRB prediction from q,
``CrbPredictor.predict``, on the Panda; ``predict.crb.single.fr3`` and ``.ur5`` on the FR3 and
the UR5, all with the impact tip); ``floor.pinocchio.all_terms`` (one ``computeAllTerms`` call,
the floor of a prediction from q) and the ratio ``predict.crb.single/floor.pinocchio.all_terms``
block by block (``base.ratio_row``); ``predict.crb.batch`` (predictions per second of
``CrbPredictor.predict_batch``, 100,000 states split over 2 worker processes, one compiled loop
each) and ``predict.crb.batch.jobs1`` (the same in one process)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio

from impactqp.controller.model.crb_prediction import CrbPredictor
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.sim.process_pool import ProcessPool

from .base import ALTERNATING_BLOCKS, alternating_blocks, blocks_row, rate_row, ratio_row, time_calls

CALLS = 5000
BATCH, BATCH_JOBS, BATCH_REPEATS = 100_000, 2, 2
_WORKER: dict[str, CrbPredictor] = {}


def single_prediction(robot: RobotModel) -> Callable[[], object]:
    """One full CRB prediction from q at the robot's first named posture, warmed up."""
    predictor = CrbPredictor(robot)
    posture = next(iter(robot.description.postures.values()))
    n = posture.surface.normal
    v = -0.15 * n

    def single():
        predictor.predict(posture.q, n, v, 0.0)

    for _ in range(200):
        single()
    return single


def _start_batch_worker(robot_name: str) -> None:
    _WORKER["crb"] = CrbPredictor(RobotModel(robot_name))


def _predict_chunk(task: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    Q, normal, velocity = task
    return _WORKER["crb"].predict_batch(Q, normal, velocity, 0.0)


def rows() -> list[dict]:
    robot = PandaModel()
    posture = next(iter(PANDA.postures.values()))
    n = posture.surface.normal
    v = -0.15 * n
    data = robot.model.createData()
    q, dq = posture.q, np.zeros(robot.nv)
    block = CALLS // ALTERNATING_BLOCKS
    timers = {
        f"predict.crb.single{suffix}": (lambda single: lambda: time_calls(single, block))(single_prediction(model))
        for suffix, model in (("", robot), (".fr3", RobotModel("fr3")), (".ur5", RobotModel("ur5")))
    }
    timers["floor.pinocchio.all_terms"] = lambda: time_calls(lambda: pinocchio.computeAllTerms(robot.model, data, q, dq), block)
    Q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (BATCH, robot.nq))
    with ProcessPool(BATCH_JOBS, _start_batch_worker, ("panda",)) as pool, ProcessPool(1, _start_batch_worker, ("panda",)) as one:
        for name, on in (("predict.crb.batch", pool), ("predict.crb.batch.jobs1", one)):
            tasks = [(chunk, n, v) for chunk in np.array_split(Q, on.jobs)]
            list(on.map(_predict_chunk, tasks))  # warm up
            timers[name] = (lambda on, tasks: lambda: time_calls(lambda: list(on.map(_predict_chunk, tasks)), BATCH_REPEATS))(on, tasks)
        blocks = alternating_blocks(timers)
    rows = [
        rate_row(name, "predictions/s", BATCH, np.concatenate(samples)) if name.startswith("predict.crb.batch")
        else blocks_row(name, "us", samples, 1e6) for name, samples in blocks.items()
    ]
    rows.append(ratio_row("predict.crb.single", "floor.pinocchio.all_terms", blocks))
    return rows
