"""Benchmark rows of the diagnosis: ``diagnose.30_trials`` (wall seconds, 2 jobs, multi-cause
search on), ``diagnose.accuracy.*`` over single (plant and sensor) and combined hidden effects,
and ``diagnose.accuracy.false_explanations``: the share of out-of-family cases (an effect
hidden while its cause is left out of the candidates) that were "explained"."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from impactqp.controller.model.choice import DEFAULT_CHOICE
from impactqp.sim.causes import CAUSE_NAMES, cause_named, default_causes, realistic_hidden_effect
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.calibration import covered
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

POSTURES = ["elbow_up", "elbow_left", "elbow_right"]
SPEEDS = [0.1, 0.18]
# combined hidden effects: three pairs and the triple that a greedy selection missed
# (docs/diagnosis.md, "Paths")
COMBINED = (
    ("armature", "payload"), ("armature", "friction"), ("joint_damping", "torque_offset"),
    ("armature", "payload", "friction"),
)
# hidden effects diagnosed without their own causes among the candidates: nothing may explain them
OUT_OF_FAMILY = (("velocity_filter",), ("torque_offset",), ("delay",), ("armature", "velocity_filter"))
JOINTS = len(DEFAULT_CHOICE.robot.joints)
"""The joints of the robot the datasets are generated with (``DatasetRequest``'s default)."""


def hidden_cases() -> list[tuple[str, ...]]:
    """Every cause alone (six plant and four sensor causes), then the ``COMBINED`` ones."""
    return [(name,) for name in CAUSE_NAMES] + list(COMBINED)


def scaled_error(cause, fitted: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """|fitted - truth| / max(|truth|, 10 % of the bounds' span): relative error, made absolute
    for a value near 0 (a CoM coordinate)."""
    span = np.array(cause.upper) - np.array(cause.lower)
    return np.abs(fitted - truth) / np.maximum(np.abs(truth), 0.1 * span)


def accuracy_of(case: tuple[str, ...], result: dict, overrides: dict) -> tuple[bool, list[float], list[bool]]:
    """Named right (the selected causes are exactly the hidden ones), the scaled error of every
    hidden parameter (inf when its cause was missed) and whether each lies in its interval
    (``calibration.covered``)."""
    named = sorted(result["causes"]) == sorted(case)
    hidden = [cause_named(name, JOINTS) for name in case]
    held = covered(hidden, result, overrides)
    errors = []
    for cause in hidden:
        if cause.name not in result["causes"]:
            errors += [float("inf")] * len(held[cause.name])
            continue
        if len(held[cause.name]) != len(cause.labels):  # ``covered`` read it through its refinement
            cause = cause.refined()
        errors += scaled_error(cause, cause.theta_of(result["parameters"]), cause.theta_of(overrides)).tolist()
    return named, errors, [h for cause in hidden for h in held[cause.name]]


def hidden_dataset(directory: Path, case: tuple[str, ...], rng: np.random.Generator, seed: int) -> dict:
    """A dataset with the realistic effects of ``case`` hidden; returns their plant overrides."""
    overrides, tangential = {}, set()
    for name in case:
        values, speeds = realistic_hidden_effect(name, rng, JOINTS)
        overrides.update(values)
        tangential.update(speeds)
    request = DatasetRequest(
        plant=PlantParameters(**overrides), postures=POSTURES, speeds=SPEEDS, tangential=sorted(tangential), seed=seed
    )
    generate_dataset(directory, request, jobs=2)
    return overrides


def false_explanations(tmp: str, rng: np.random.Generator) -> float:
    """The share of the ``OUT_OF_FAMILY`` cases that the diagnosis "explained" (goal 0)."""
    explained = []
    for k, case in enumerate(OUT_OF_FAMILY):
        data = Path(tmp) / f"outside{k}"
        hidden_dataset(data, case, rng, 100 + k)
        causes = [c for c in default_causes(JOINTS) if c.name not in case]
        explained.append(diagnose(data, causes=causes, jobs=2).explained)
    return float(np.mean(explained))


def thirty_trial_rows() -> list[dict]:
    """diagnose.30_trials: the wall seconds of ``diagnose`` (2 jobs, every default candidate) on 30
    trials (every posture x the default speeds x 2 repeats) with a realistic armature hidden."""
    overrides, _ = realistic_hidden_effect("armature", np.random.default_rng(2026), JOINTS)
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "thirty"
        generate_dataset(data, DatasetRequest(plant=PlantParameters(**overrides), repeats=2, seed=1), jobs=2)
        start = time.perf_counter()
        diagnose(data, jobs=2)
        elapsed = time.perf_counter() - start
    return [{"name": "diagnose.30_trials", "unit": "s", "median": elapsed, "p99": elapsed}]


def accuracy_rows() -> list[dict]:
    """diagnose.accuracy.{named, parameter_error, coverage, false_explanations}."""
    rng = np.random.default_rng(2026)
    realistic_hidden_effect("armature", rng, JOINTS)  # the 30-trial dataset's draw: the cases' draws follow it
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        named, errors, covered = [], [], []
        for k, case in enumerate(hidden_cases()):
            overrides = hidden_dataset(Path(tmp) / f"hidden{k}", case, rng, k)
            result = diagnose(Path(tmp) / f"hidden{k}", jobs=2).summary()
            case_named, case_errors, case_covered = accuracy_of(case, result, overrides)
            named.append(case_named)
            errors += case_errors
            covered += case_covered
        false_share = false_explanations(tmp, rng)
    share = float(np.mean(named))
    rows.append({"name": "diagnose.accuracy.named", "unit": "share", "median": share, "p99": share})
    rows.append(
        {
            "name": "diagnose.accuracy.parameter_error",
            "unit": "relative",
            "median": float(np.median(errors)),
            "p99": float(np.percentile(errors, 99, method="higher")),  # inf when a cause was missed
        }
    )
    coverage = float(np.mean(covered))
    rows.append({"name": "diagnose.accuracy.coverage", "unit": "share", "median": coverage, "p99": coverage})
    rows.append(
        {"name": "diagnose.accuracy.false_explanations", "unit": "share", "median": false_share, "p99": false_share}
    )
    return rows
