"""Row helpers of the benchmark table: every row is ``{"name", "unit", "median", "p99"}``.

Times are measured over many repetitions and summarised by their median and 99th percentile; for a
rate (per second), "p99" is the rate at the 99th-percentile time, i.e. the slow tail.
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
