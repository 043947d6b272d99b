"""Benchmark rows of the diagnosis: ``diagnose.30_trials`` (wall seconds, 2 jobs) and
``diagnose.accuracy.*`` over hidden effects."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from impactqp.sim.causes import CAUSE_NAMES, cause_named, realistic_hidden_effect
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import generate_dataset
from impactqp.sim.plant import PlantParameters


def rows() -> list[dict]:
    """diagnose.30_trials (wall s, 2 jobs) and diagnose.accuracy over 10 hidden effects."""
    mujoco.set_mju_user_warning(lambda message: None)
    rng = np.random.default_rng(2026)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        overrides, _ = realistic_hidden_effect("armature", rng)
        data = Path(tmp) / "thirty"
        generate_dataset(data, plant=PlantParameters(**overrides), repeats=2, seed=1, jobs=2)
        start = time.perf_counter()
        diagnose(data, jobs=2)
        elapsed = time.perf_counter() - start
        rows.append({"name": "diagnose.30_trials", "unit": "s", "median": elapsed, "p99": elapsed})
        named, errors = [], []
        for k in range(10):
            cause = str(rng.choice(CAUSE_NAMES))
            overrides, tangential = realistic_hidden_effect(cause, rng)
            data = Path(tmp) / f"hidden{k}"
            generate_dataset(
                data, plant=PlantParameters(**overrides), speeds=[0.1, 0.18], tangential=tangential, seed=k, jobs=2
            )
            result = diagnose(data, jobs=2).summary()
            named.append(result["cause"] == cause)
            truth = cause_named(cause).theta_of(overrides)
            if result["cause"] == cause:
                errors.append(float(np.max(np.abs(cause_named(cause).theta_of(result["parameters"]) / truth - 1))))
            else:
                errors.append(float("inf"))
    rows.append({"name": "diagnose.accuracy.named", "unit": "share", "median": float(np.mean(named)), "p99": float(np.mean(named))})
    rows.append(
        {
            "name": "diagnose.accuracy.parameter_error",
            "unit": "relative",
            "median": float(np.median(errors)),
            "p99": float(np.percentile(errors, 99)),
        }
    )
    return rows
