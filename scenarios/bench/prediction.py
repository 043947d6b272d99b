"""Benchmark rows of the jump predictors, all timed in alternating blocks in one run
(``base.alternating_blocks``): ``predict.crb.single`` (one full CRB prediction from q,
``CrbPredictor.predict``, on the Panda; ``predict.crb.single.fr3`` and ``.ur5`` on the FR3 and
the UR5, all with the impact tip); ``floor.pinocchio.all_terms`` (one ``computeAllTerms`` call,
the floor of a prediction from q) and the ratio ``predict.crb.single/floor.pinocchio.all_terms``
block by block (``base.ratio_row``); ``predict.crb.batch`` (predictions per second of
``CrbPredictor.predict_batch``, 100,000 states in shared memory split over 2 worker processes,
one compiled loop each writing its rows in place), ``predict.crb.batch.cpu`` (the same batch over
the workers' CPU time: BATCH / (their CPU seconds / BATCH_JOBS), the rate the run would reach on
dedicated cores, whatever else the machine runs) and ``predict.crb.batch.jobs1`` (the same in
one process)."""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable
from contextlib import ExitStack

import numpy as np
import pinocchio

from impactqp.controller.model.crb_prediction import CrbPredictor
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.sim.process_pool import ProcessPool

from .base import ALTERNATING_BLOCKS, alternating_blocks, blocks_row, rate_row, ratio_row, time_calls

CALLS = 5000
BATCH, BATCH_JOBS, BATCH_REPEATS = 100_000, 2, 2
BATCH_ARRAYS = ("Q", "jumps", "impulses")
SHARED_MEMORY = "/dev/shm" if os.path.isdir("/dev/shm") else None
"""Where the batch's arrays are mapped from: memory, where the system has it as a folder."""
_WORKER: dict[str, object] = {}


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


def _start_batch_worker(robot_name: str, folder: str) -> None:
    """A worker's predictor and the batch's arrays, memory-mapped from the ``.npy`` files of
    ``folder`` (shared memory: the states Q read, the jumps and impulses written in place)."""
    _WORKER["crb"] = CrbPredictor(RobotModel(robot_name))
    _WORKER.update({name: np.load(os.path.join(folder, f"{name}.npy"), mmap_mode="r+") for name in BATCH_ARRAYS})


def _predict_rows(task: tuple[int, int, np.ndarray, np.ndarray]) -> float:
    """The batch's rows [start, stop) for the normal n and the velocity v-, predicted into the
    mapped jumps and impulses; the CPU seconds this process spent on them."""
    start, stop, normal, velocity = task
    Q, jumps, impulses = (_WORKER[name] for name in BATCH_ARRAYS)
    cpu = time.process_time()
    _WORKER["crb"].predict_batch(Q[start:stop], normal, velocity, 0.0, out=(jumps[start:stop], impulses[start:stop]))
    return time.process_time() - cpu


class BatchTimer:
    """The timer of one pool's batch (``alternating_blocks``): each call maps the tasks
    BATCH_REPEATS times and returns the wall seconds of each; ``cpu`` keeps, per batch, the
    workers' CPU seconds over the number of workers (the batch's time on dedicated cores)."""

    def __init__(self, pool: ProcessPool, tasks: list):
        self.pool, self.tasks, self.cpu = pool, tasks, []

    def __call__(self) -> np.ndarray:
        samples = np.empty(BATCH_REPEATS)
        for k in range(BATCH_REPEATS):
            start = time.perf_counter()
            cpu = sum(self.pool.map(_predict_rows, self.tasks))
            samples[k] = time.perf_counter() - start
            self.cpu.append(cpu / len(self.tasks))
        return samples


def batch_timers(robot: RobotModel, folder: str, stack: ExitStack, impact: tuple[np.ndarray, np.ndarray]) -> dict:
    """The timers (``BatchTimer``) of ``predict.crb.batch`` (BATCH_JOBS worker processes) and
    ``.jobs1`` (this process): BATCH random states in shared memory (``folder``), each worker
    predicting its share of the rows in one compiled loop; warmed up."""
    Q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (BATCH, robot.nq))
    shapes = {"Q": Q.shape, "jumps": (BATCH, robot.nv), "impulses": (BATCH, 3)}
    for name in BATCH_ARRAYS:
        np.lib.format.open_memmap(os.path.join(folder, f"{name}.npy"), "w+", float, shapes[name])[:] = Q if name == "Q" else 0.0
    timers = {}
    for name, jobs in (("predict.crb.batch", BATCH_JOBS), ("predict.crb.batch.jobs1", 1)):
        pool = stack.enter_context(ProcessPool(jobs, _start_batch_worker, (robot.description.name, folder)))
        bounds = np.linspace(0, BATCH, jobs + 1).astype(int)
        tasks = [(int(a), int(b), *impact) for a, b in zip(bounds[:-1], bounds[1:])]
        list(pool.map(_predict_rows, tasks))  # warm up
        timers[name] = BatchTimer(pool, tasks)
    return timers


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
    with tempfile.TemporaryDirectory(dir=SHARED_MEMORY) as folder, ExitStack() as stack:
        timers.update(batch_timers(robot, folder, stack, (n, v)))
        blocks = alternating_blocks(timers)
    rows = [
        rate_row(name, "predictions/s", BATCH, np.concatenate(samples)) if name.startswith("predict.crb.batch")
        else blocks_row(name, "us", samples, 1e6) for name, samples in blocks.items()
    ]
    cpu = timers["predict.crb.batch"].cpu
    rows.insert(-1, rate_row("predict.crb.batch.cpu", "predictions/s", BATCH, np.array(cpu)))
    rows.append(ratio_row("predict.crb.single", "floor.pinocchio.all_terms", blocks))
    return rows
