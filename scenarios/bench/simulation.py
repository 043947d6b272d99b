"""Benchmark rows of the simulation: ``sim.closed_loop_rtf`` (simulated seconds per wall-clock
second, controller in the loop) and ``maxspeed.one_posture`` (wall seconds of one search)."""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.scenarios.max_speed_search import MaxSpeedSearch
from impactqp.scenarios.trial import TrialRunner
from impactqp.sim.runner import TrialSpec

from .base import rate_row, time_calls, timing_row


def closed_loop_benchmark_rows(repeats: int = 5) -> list[dict]:
    """``sim.closed_loop_rtf``: simulated seconds per wall-clock second of a trial with the QP
    controller in the loop (elbow_up, 0.15 m/s, crb constraints on, moving start)."""

    runner = TrialRunner.build(DEFAULT_WALL)
    spec = TrialSpec("elbow_up", PANDA.postures["elbow_up"].q, 0.15, jump_model="crb")
    logs = [runner.run(spec).log for _ in range(repeats)]
    simulated = len(logs[0]) * logs[0].control_period
    return [rate_row("sim.closed_loop_rtf", "sim s / wall s", simulated, np.array([log.wall_time for log in logs]))]


def max_speed_benchmark_rows(repeats: int = 3) -> list[dict]:
    """``maxspeed.one_posture``: wall seconds of the whole search on elbow_up with 2 jobs."""

    search = MaxSpeedSearch(PANDA.postures["elbow_up"], DEFAULT_WALL, jobs=2)
    return [timing_row("maxspeed.one_posture", "s", time_calls(search.run, repeats), 1.0)]
