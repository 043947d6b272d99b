"""Row helpers of the benchmark table: every row is ``{"name", "unit", "median", "p99"}``.

Times are measured over many repetitions and summarised by their median and 99th percentile; for a
rate (per second), "p99" is the rate at the 99th-percentile time, i.e. the slow tail.

A row and the floor it is compared with are timed in alternating blocks in one process
(``alternating_blocks``): the machine's slow phases (1.5-2x on a shared machine) then fall on
both alike, and their ratio (``ratio_row``) is taken block by block.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def timing_row(name: str, unit: str, samples_s: np.ndarray, scale: float) -> dict:
    samples = np.asarray(samples_s) * scale
    return {"name": name, "unit": unit, "median": float(np.median(samples)), "p99": float(np.percentile(samples, 99))}


def missing_row(name: str, unit: str, note: str) -> dict:
    """A row that could not be measured on this machine: median and p99 are None (null in
    JSON), ``note`` says why."""
    return {"name": name, "unit": unit, "median": None, "p99": None, "note": note}


def rate_row(name: str, unit: str, count: int, samples_s: np.ndarray) -> dict:
    samples = np.asarray(samples_s)
    return {
        "name": name,
        "unit": unit,
        "median": float(count / np.median(samples)),
        "p99": float(count / np.percentile(samples, 99)),
    }


def time_calls(fn: Callable[[], object], repeats: int) -> np.ndarray:
    samples = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples[i] = time.perf_counter() - t0
    return samples


ALTERNATING_BLOCKS = 8


def alternating_blocks(timers: dict[str, Callable[[], np.ndarray]], blocks: int = ALTERNATING_BLOCKS) -> dict[str, list[np.ndarray]]:
    """Each timer's ``blocks`` blocks of samples (seconds), the timers called in turn, block after
    block (each call times one block)."""
    samples: dict[str, list[np.ndarray]] = {name: [] for name in timers}
    for _ in range(blocks):
        for name, timer in timers.items():
            samples[name].append(timer())
    return samples


def blocks_row(name: str, unit: str, blocks: list[np.ndarray], scale: float) -> dict:
    """The timing row of all the blocks' samples together."""
    return timing_row(name, unit, np.concatenate(blocks), scale)


def ratio_row(numerator: str, denominator: str, blocks: dict[str, list[np.ndarray]]) -> dict:
    """The row ``numerator/denominator`` of two timers of one ``alternating_blocks`` run: the ratio
    of their medians in each block, its median over the blocks ("median") and its 99th
    percentile ("p99", the least favourable block)."""
    ratios = [float(np.median(a) / np.median(b)) for a, b in zip(blocks[numerator], blocks[denominator])]
    return {
        "name": f"{numerator}/{denominator}", "unit": "ratio",
        "median": float(np.median(ratios)), "p99": float(np.percentile(ratios, 99)),
    }
