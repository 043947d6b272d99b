"""Benchmark rows of the jump predictors: ``predict.crb.single`` (one full CRB prediction from q,
on the Panda; ``predict.crb.single.fr3`` and ``.ur5`` on the FR3 and the UR5, all with the impact tip)
and ``predict.crb.batch`` (predictions per second of the vectorised batch API);
``floor.pinocchio.all_terms`` (one ``computeAllTerms`` call, the floor of a prediction from q),
timed in alternating blocks with ``predict.crb.single``, and their ratio
``predict.crb.single/floor.pinocchio.all_terms`` block by block (``base.ratio_row``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio

from impactqp.controller.model.batch import BatchKinematics, predict_batch
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, RobotModel

from .base import ALTERNATING_BLOCKS, alternating_blocks, blocks_row, rate_row, ratio_row, time_calls, timing_row

CALLS = 5000


def single_prediction(robot: RobotModel) -> Callable[[], object]:
    """One full CRB prediction from q at the robot's first named posture, warmed up."""
    crb = JUMP_MODELS["crb"]
    posture = next(iter(robot.description.postures.values()))
    n = posture.surface.normal
    v = -0.15 * n

    def single():
        crb.predict(robot.terms(posture.q), n, v, 0.0)

    for _ in range(200):
        single()
    return single


def rows() -> list[dict]:
    robot = PandaModel()
    posture = next(iter(PANDA.postures.values()))
    n = posture.surface.normal
    v = -0.15 * n
    data = robot.model.createData()
    q, dq = posture.q, np.zeros(robot.nv)
    single = single_prediction(robot)
    block = CALLS // ALTERNATING_BLOCKS
    blocks = alternating_blocks({
        "predict.crb.single": lambda: time_calls(single, block),
        "floor.pinocchio.all_terms": lambda: time_calls(lambda: pinocchio.computeAllTerms(robot.model, data, q, dq), block),
    })
    rows = [blocks_row(name, "us", samples, 1e6) for name, samples in blocks.items()]
    rows.append(ratio_row("predict.crb.single", "floor.pinocchio.all_terms", blocks))
    for name in ("fr3", "ur5"):
        rows.append(timing_row(f"predict.crb.single.{name}", "us", time_calls(single_prediction(RobotModel(name)), CALLS), 1e6))
    kinematics = BatchKinematics(robot)
    Q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (10_000, robot.nq))
    predict_batch(kinematics, Q, n, v, 0.0, "crb")
    samples = time_calls(lambda: predict_batch(kinematics, Q, n, v, 0.0, "crb"), 30)
    rows.append(rate_row("predict.crb.batch", "predictions/s", 10_000, samples))
    return rows
