"""The benchmark table of ``impactqp bench``: every tracked speed and accuracy figure.

Each row is ``{"name", "unit", "median", "p99"}``. Times are measured over many repetitions and
summarised by their median and 99th percentile; for a rate (per second), "p99" is the rate at the
99th-percentile time, i.e. the slow tail. Goals are printed in the docs, never asserted.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def timing_row(name: str, unit: str, samples_s: np.ndarray, scale: float) -> dict:
    samples = np.asarray(samples_s) * scale
    return {"name": name, "unit": unit, "median": float(np.median(samples)), "p99": float(np.percentile(samples, 99))}


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


def prediction_rows() -> list[dict]:
    from impactqp.controller.model.batch import BatchKinematics, predict_batch
    from impactqp.controller.model.jump import JUMP_MODELS
    from impactqp.controller.model.postures import POSTURES
    from impactqp.controller.model.robot import PandaModel

    robot = PandaModel()
    crb = JUMP_MODELS["crb"]
    posture = next(iter(POSTURES.values()))
    n = posture.surface.normal
    v = -0.15 * n

    def single():
        crb.predict(robot.terms(posture.q), n, v, 0.0)

    for _ in range(200):
        single()
    rows = [timing_row("predict.crb.single", "us", time_calls(single, 5000), 1e6)]
    kinematics = BatchKinematics(robot)
    Q = np.random.default_rng(0).uniform(robot.q_min, robot.q_max, (10_000, 7))
    predict_batch(kinematics, Q, n, v, 0.0, "crb")
    samples = time_calls(lambda: predict_batch(kinematics, Q, n, v, 0.0, "crb"), 30)
    rows.append(rate_row("predict.crb.batch", "predictions/s", 10_000, samples))
    return rows


def controller_rows() -> list[dict]:
    from impactqp.scenarios.bench.controller import controller_rows as rows

    return rows()


def closed_loop_rows() -> list[dict]:
    from impactqp.scenarios.trial import closed_loop_benchmark_rows

    return closed_loop_benchmark_rows()


def max_speed_rows() -> list[dict]:
    from impactqp.scenarios.max_speed_search import max_speed_benchmark_rows

    return max_speed_benchmark_rows()


def diagnosis_rows() -> list[dict]:
    """diagnose.30_trials (wall s, 2 jobs) and diagnose.accuracy over 10 hidden effects."""
    import tempfile
    from pathlib import Path

    import mujoco

    from impactqp.sim.causes import CAUSE_NAMES, cause_named, realistic_hidden_effect
    from impactqp.sim.diagnosis import diagnose
    from impactqp.sim.generation import generate_dataset
    from impactqp.sim.plant import PlantParameters

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


BENCHMARKS: list[tuple[str, Callable[[], list[dict]]]] = [
    ("predict.", prediction_rows),
    ("controller.", controller_rows),
    ("sim.closed_loop", closed_loop_rows),
    ("maxspeed.", max_speed_rows),
    ("diagnose.", diagnosis_rows),
]


def run_benchmarks(only: str = "", progress: bool = True) -> list[dict]:
    rows = []
    for prefix, fn in BENCHMARKS:
        if only and not (prefix.startswith(only) or only.startswith(prefix)):
            continue
        if progress:
            print(f"running {prefix}* ...", flush=True)
        rows.extend(r for r in fn() if r["name"].startswith(only))
    return rows
