"""Whether a diagnosis's 95 % intervals hold a known truth: the coverage of simulated datasets
whose hidden plant is known (the benchmark's ``diagnose.coverage`` rows, ``docs/diagnosis.md``).

A parameter **family** is one cause's parameters (armature, payload, ...). For each hidden cause
of a dataset, every true parameter either lies in the interval the diagnosis reports for it or
not; a cause the diagnosis did not name holds none of its truths (``covered``). Over many
datasets, the share of truths held per family (``coverage``) is the intervals' calibration: a
95 % interval should hold the truth in about 95 % of the datasets.
"""

from __future__ import annotations

import numpy as np

from impactqp.sim.causes import Cause

from .intervals import holds


def covered(hidden: list[Cause], result: dict, truth: dict) -> dict[str, list[bool]]:
    """Per hidden cause (its ``name``, the family), whether each of its true parameters (read
    from the plant overrides ``truth`` that made the dataset) lies in the interval of
    ``result`` (``Diagnosis.summary()``: its ``parameter_intervals``); a cause that ``result``
    does not name covers nothing. A cause the search refined (the velocity scale per joint: more
    intervals than the cause has parameters) is read through its refinement."""
    found = {}
    for cause in hidden:
        intervals = [row["interval"] for row in result["parameter_intervals"] if row["cause"] == cause.name]
        if cause.name not in result["causes"]:
            found[cause.name] = [False] * len(cause.theta_of(truth))
            continue
        if len(intervals) != len(cause.labels) and cause.refined() is not None:
            cause = cause.refined()
        found[cause.name] = [holds(float(v), interval) for v, interval in zip(cause.theta_of(truth), intervals)]
    return found


def coverage(results: list[dict[str, list[bool]]]) -> dict[str, float]:
    """The share of truths held per family over many datasets' ``covered``."""
    families: dict[str, list[bool]] = {}
    for result in results:
        for family, held in result.items():
            families.setdefault(family, []).extend(held)
    return {family: float(np.mean(held)) for family, held in families.items()}
