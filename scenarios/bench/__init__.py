"""The benchmark table of ``impactqp bench``: every tracked speed and accuracy figure.

One module per family (``prediction``, ``controller``, ``whole_body``, ``simulation``, ``diagnosis``), each with
row helpers from ``base``. Goals are ratios within one run, printed in docs/benchmarks.md, never asserted
in tests.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from importlib import import_module

from impactqp.controller.model.validation import BadInputError

__all__ = ["run_benchmarks"]

log = logging.getLogger(__name__)

FAMILIES: list[tuple[str, str, str]] = [
    # (row-name prefix, module, function returning the rows)
    ("predict.", "prediction", "rows"),
    ("controller.", "controller", "controller_rows"),  # with its peer.* rows
    ("controller.cycle.g1", "whole_body", "rows"),  # the standing G1's, with pink's row of the same problem
    ("sim.closed_loop", "simulation", "closed_loop_benchmark_rows"),
    ("maxspeed.", "simulation", "max_speed_benchmark_rows"),
    ("diagnose.30_trials", "diagnosis", "thirty_trial_rows"),
    ("diagnose.accuracy", "diagnosis", "accuracy_rows"),
    ("diagnose.cases", "diagnosis_cases", "case_rows"),  # fixed multi-cause diagnoses, minutes each
    ("diagnose.coverage", "diagnosis_coverage", "coverage_rows"),  # the intervals' calibration (long)
    ("diagnose.false_explanations", "diagnosis_coverage", "false_explanation_rows"),
    ("loop.", "loop", "rows"),
    ("loop.franka_sim", "loop", "franka_sim_loop_rows"),  # one franky-sim run for both rows
    ("impact.", "loop", "detection_rows"),
    ("impact.detection_latency.franka_sim", "loop", "franka_sim_detection_rows"),
    ("sweep.", "sweep", "rows"),
]


def _family(module: str, function: str) -> Callable[[], list[dict]]:
    return getattr(import_module(f"{__name__}.{module}"), function)


def run_benchmarks(only: str = "") -> list[dict]:
    """The rows whose name starts with ``only`` (all rows when empty), each family announced as it
    starts (a note: INFO); a prefix that selects no family is bad input (naming the families)."""
    if only and not any(prefix.startswith(only) or only.startswith(prefix) for prefix, _, _ in FAMILIES):
        known = ", ".join(dict.fromkeys(prefix.rstrip(".") for prefix, _, _ in FAMILIES))
        raise BadInputError(f"--only {only!r} selects no benchmark row; the rows start with {known}")
    rows = []
    # a prefix within a more specific family's (``--only diagnose.coverage``) runs that family only
    within = [prefix for prefix, _, _ in FAMILIES if only.startswith(prefix)]
    for prefix, module, function in FAMILIES:
        if only and not (prefix.startswith(only) or only.startswith(prefix)):
            continue
        if only and any(len(other) > len(prefix) for other in within) and only.startswith(prefix):
            continue
        log.info("bench: running %s* ...", prefix)
        rows.extend(r for r in _family(module, function)() if _selected(r["name"], only, prefix))
    return rows


# Reference rows timed inside a family, so that the family's goals are ratios within one run:
# they are kept with the family's own rows (``--only controller`` keeps the peers).
COMPANION_PREFIXES = ("peer.", "floor.")


def _selected(name: str, only: str, family_prefix: str) -> bool:
    if name.startswith(only):
        return True
    return family_prefix.startswith(only) and name.startswith(COMPANION_PREFIXES)
