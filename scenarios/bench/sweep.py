"""Benchmark rows of ``impactqp sweep``: closed-form cells per second at 1 and 2 workers."""

from __future__ import annotations

import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config

REPEATS = 3


def _config():
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.4, 0.4], spacing=0.025)  # 17 x 17 points
    data["settings"].update(restitution=[0.0, 0.5], jump_models=["classical", "gm", "crb"])
    return parse_config(data)


def rows() -> list[dict]:
    config = _config()
    cells = config.cell_count()
    out = []
    for jobs in (1, 2):
        samples = np.empty(REPEATS)
        for i in range(REPEATS):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                run_sweep(config, Path(tmp) / "sweep", jobs=jobs, progress=False, plots=False)
                samples[i] = time.perf_counter() - t0
        out.append(
            {
                "name": f"sweep.closed_form.cells_per_s.jobs{jobs}",
                "unit": "cells/s",
                "median": float(cells / np.median(samples)),
                "p99": float(cells / np.percentile(samples, 99)),
            }
        )
    return out
