"""Benchmark rows of fixed multi-cause diagnoses (``diagnose.cases.*``): hidden plants whose
search was once wrong and was fixed (docs/diagnosis.md), kept as accuracy rows rather than
pass/fail tests (each takes minutes). Per case, ``diagnose.cases.<case>.named`` is 1 when the
diagnosis names exactly the hidden causes and calls the data explained, else 0, and
``diagnose.cases.<case>.coverage`` is the share of the hidden values that lie in their
reported 95 % intervals (``calibration.covered``; a cause not named holds none of its truths).

- ``pair``: armature per group and a payload (every default candidate);
- ``greedy_triple``: armature, payload and friction with tangential speeds, the triple a greedy
  forward selection missed (every default candidate);
- ``masked_triple``: the three large enough that none alone gains a step held out (the coverage
  study's draw of seed 6005; the three hidden causes are the only candidates);
- ``one_gains_triple``: the three again, where the payload alone just gains a step held out and
  no forward step from it does, so the path from it ends without fitting the noise (the
  coverage study's draw of seed 6009; the three hidden causes are the only candidates);
- ``second_cause``: joint damping on the first four joints and one joint's velocity logged 5 %
  too large, which damping alone fits to the noise in every block but not on that joint's
  channel (damping and the velocity scale the candidates).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from impactqp.sim.causes import ArmatureCause, FrictionCause, JointDampingCause, PayloadCause, VelocityScaleCause, per_group
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

from .diagnosis import JOINTS, POSTURES, SPEEDS, accuracy_of

SMALL_POSTURES = POSTURES[:2]
SCALED_JOINT = 5
"""The joint (0-based) whose logged velocity ``second_cause`` scales."""


@dataclass(frozen=True)
class FixedCase:
    """A hidden plant (``truth``: plant overrides), its dataset and the candidates diagnosed."""

    name: str
    causes: tuple[str, ...]  # the hidden causes, by name
    truth: dict
    request: dict  # DatasetRequest keywords besides the plant
    candidates: tuple = field(default=())  # cause objects; empty: every default candidate


def fixed_cases() -> list[FixedCase]:
    """The cases of the module docstring, for the robot the datasets are generated with."""
    scale = [1.0] * JOINTS
    scale[SCALED_JOINT] = 1.05
    small = {"postures": SMALL_POSTURES, "speeds": SPEEDS}
    return [
        FixedCase(
            "pair", ("armature", "payload"),
            {"armature": per_group((0.6, 0.15), JOINTS), "payload_mass": 1.0, "payload_com": [0.01, -0.01, -0.06]},
            {"postures": POSTURES, "speeds": SPEEDS, "seed": 7},
        ),
        FixedCase(
            "greedy_triple", ("armature", "friction", "payload"),
            {"armature": per_group((0.3, 0.15), JOINTS), "payload_mass": 0.4, "payload_com": [0.01, 0.0, -0.05],
             "friction": 0.4},
            {**small, "repeats": 2, "tangential": [0.3, 0.6], "seed": 8},
        ),
        FixedCase(
            "masked_triple", ("armature", "friction", "payload"),
            {"armature": per_group((1.25, 0.06), JOINTS), "payload_mass": 1.14, "payload_com": [0.016, -0.012, -0.027],
             "friction": 0.62},
            {**small, "tangential": [0.3, 0.6], "seed": 6005},
            (ArmatureCause(JOINTS), PayloadCause(), FrictionCause()),
        ),
        FixedCase(
            "one_gains_triple", ("armature", "friction", "payload"),
            {"armature": per_group((1.4976, 0.2209), JOINTS), "payload_mass": 1.4475,
             "payload_com": [0.0006, -0.0046, -0.0343], "friction": 0.5217},
            {**small, "tangential": [0.3, 0.6], "seed": 6009},
            (ArmatureCause(JOINTS), PayloadCause(), FrictionCause()),
        ),
        FixedCase(
            "second_cause", ("joint_damping", "velocity_scale"),
            {"joint_damping": [1.0] * 4 + [0.0] * (JOINTS - 4), "sensor_joint_velocity_scale": scale},
            {**small, "repeats": 2, "seed": 4},
            (JointDampingCause(JOINTS), VelocityScaleCause(JOINTS)),
        ),
    ]


def case_result(case: FixedCase, directory: Path) -> tuple[float, float]:
    """(named: 1.0 or 0.0, coverage) of one case's dataset generated in ``directory``."""
    generate_dataset(directory, DatasetRequest(plant=PlantParameters(**case.truth), **case.request), jobs=2)
    diagnosis = diagnose(directory, causes=list(case.candidates) or None, jobs=2)
    named, _, held = accuracy_of(case.causes, diagnosis.summary(), case.truth)
    return float(named and diagnosis.explained), sum(held) / len(held)


def case_rows() -> list[dict]:
    """diagnose.cases.<case>.named and .coverage for every fixed case."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in fixed_cases():
            named, coverage = case_result(case, Path(tmp) / case.name)
            rows.append({"name": f"diagnose.cases.{case.name}.named", "unit": "named", "median": named, "p99": named})
            rows.append(
                {"name": f"diagnose.cases.{case.name}.coverage", "unit": "share", "median": coverage, "p99": coverage}
            )
    return rows
