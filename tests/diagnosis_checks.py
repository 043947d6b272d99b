"""Shared by the tests of the diagnosis package (sim/diagnosis/): the datasets' postures and
speeds, the JSON contract of ``diagnose --json``, and synthetic trials that need no simulation."""

from __future__ import annotations

import numpy as np

from conftest import JOINTS
from impactqp.controller.measured.impact import POST_HALF_WIDTH, PRE_SAMPLES
from impactqp.sim.diagnosis.noise import BlockNoise
from impactqp.sim.diagnosis.trials import MeasuredTrial, ReplayFeatures
from impactqp.sim.plant import PlantParameters

POSTURES = ["elbow_up", "elbow_left", "elbow_right"]
SPEEDS = [0.1, 0.18]


def inside(value: float, interval) -> bool:
    low, high = interval
    return (low is None or low <= value) and (high is None or value <= high)


def check_contract(result: dict) -> None:
    """The JSON contract of ``diagnose --json``: intervals per parameter key, steps, causes."""
    assert set(result["intervals"]) == set(result["parameters"])
    for key, value in result["parameters"].items():
        interval = result["intervals"][key]
        if isinstance(value, list):
            assert len(interval) == len(value) and all(len(pair) == 2 for pair in interval)
            assert all(inside(v, pair) for v, pair in zip(value, interval))
        else:
            assert len(interval) == 2 and inside(value, interval)
    assert [s["cause"] for s in result["steps"] if s["selected"]] == result["causes"]
    assert result["cause"] == (result["causes"][0] if result["causes"] else result["cause"])
    PlantParameters.from_dict(result["parameters"])  # usable with --plant


def tolerance(cause, truth: np.ndarray) -> np.ndarray:
    """20 % of each value, at least 2 % of its bounds' span (a CoM coordinate near 0)."""
    return 0.2 * np.maximum(np.abs(truth), 0.1 * (np.array(cause.upper) - np.array(cause.lower)))


def synthetic_trial(rng: np.random.Generator, *, force: bool = True, speed: float = 0.1,
                    posture: str | None = "elbow_up", samples: int = 60) -> MeasuredTrial:
    """A trial of random numbers with the shapes of a real one (no simulation, no file)."""
    pre = PRE_SAMPLES + 10
    post = pre + POST_HALF_WIDTH + 3
    return MeasuredTrial(
        id=f"s{rng.integers(10**6)}",
        posture=posture,
        reference_speed=speed,
        tangential_speed=0.0,
        q0=rng.normal(size=JOINTS),
        dq0=rng.normal(size=JOINTS),
        servo_reference=(rng.normal(size=JOINTS), rng.normal(size=JOINTS)),
        dq_cmd=rng.normal(size=(samples, JOINTS)),
        control_period=1e-3,
        jump=rng.normal(size=JOINTS),
        impulse=rng.normal(size=3) if force else None,
        duration=float(rng.uniform(1e-3, 1e-2)) if force else None,
        torque=rng.normal(size=JOINTS),
        q_pre=rng.normal(size=JOINTS),
        dq_pre=rng.normal(size=JOINTS),
        torque_window=(5, 15),
        dq_log=rng.normal(size=(samples, JOINTS)),
        tau_log=rng.normal(size=(samples, JOINTS)),
        jump_samples=(pre, post),
        scatter=(rng.uniform(1e-6, 1e-4, JOINTS), rng.uniform(1e-4, 1e-2, JOINTS)),
        force_period=2.5e-4 if force else None,
        noise=BlockNoise(rng.uniform(1e-3, 1e-2, JOINTS), rng.uniform(1e-2, 0.1, JOINTS), rng.uniform(1e-3, 1e-2, 3), 3e-4,
                         rng.uniform(1e-3, 1e-2, 2 * JOINTS)),
    )


def exact_features(trial: MeasuredTrial) -> ReplayFeatures:
    """What a replay that reproduces ``trial`` exactly would give."""
    return ReplayFeatures(trial.reference, trial.impulse, trial.duration, trial.torque, trial.jump,
                          trial.reference_trace)
