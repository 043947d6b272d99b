"""Benchmark rows of ``impactqp sweep``: closed-form cells per second at 1 and 2 workers (batched
inverse kinematics and closed form), and simulated cells per minute at 2 workers."""

from __future__ import annotations

import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.cells import Simulation
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config

REPEATS = 3


def _closed_form_config():
    """81 x 81 points (about half of them reachable) x 2 restitution values, 3 jump models."""
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.4, 0.4], spacing=0.005)
    data["settings"].update(restitution=[0.0, 0.5], jump_models=["classical", "gm", "crb"])
    return parse_config(data)


def _simulated_config():
    """3 x 3 reachable contact points below and beside the tip of elbow_up, the default tolerance."""
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(origin=[0.6, -0.1, 0.6], size=[0.1, 0.1], spacing=0.05)
    return parse_config(data)


def _wall_times(config, jobs: int, repeats: int, simulation: Simulation | None = None) -> np.ndarray:
    samples = np.empty(repeats)
    for i in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run_sweep(config, Path(tmp) / "sweep", jobs=jobs, progress=False, plots=False, simulation=simulation)
            samples[i] = time.perf_counter() - t0
    return samples


def rows() -> list[dict]:
    config = _closed_form_config()
    cells = config.cell_count()
    out = []
    for jobs in (1, 2):
        samples = _wall_times(config, jobs, REPEATS)
        out.append(
            {
                "name": f"sweep.closed_form.cells_per_s.jobs{jobs}",
                "unit": "cells/s",
                "median": float(cells / np.median(samples)),
                "p99": float(cells / np.percentile(samples, 99)),
            }
        )
    config = _simulated_config()
    samples = _wall_times(config, 2, 1, Simulation())
    out.append(
        {
            "name": "sweep.simulated.cells_per_min.jobs2",
            "unit": "cells/min",
            "median": float(60.0 * config.cell_count() / np.median(samples)),
            "p99": float(60.0 * config.cell_count() / np.percentile(samples, 99)),
        }
    )
    return out
