"""The figure of ``impactqp max-speed --figure``: a posture's highest feasible contact speed per
predictor (the closed form of each, and ``robust``, the smallest: docs/max-speed.md) beside the
speeds the simulation reached (an arm's QP-limited run and the bisection without jump
constraints; a standing robot's bisection), one horizontal bar each, every predictor's bar
naming what binds it (the criterion and the joint, or where it binds). Written atomically in the
format of the file's suffix (``scenarios.impact_figure.check_figure_suffix``).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .campaign_figures import save_figure  # noqa: E402
from .impact_figure import check_figure_suffix  # noqa: E402
from .max_speed_search import binding_text  # noqa: E402

SIMULATED = {"qp_limited_speed": "QP-limited run", "simulated_max_speed": "simulated bisection"}


def bars(report: dict) -> list[tuple[str, float, str]]:
    """The bars of a ``max-speed`` JSON report: (label, speed m/s, annotation), the predictors
    first (an unbounded one left out), then the simulated speeds the report has."""
    rows = [(f"{name} (closed form)", speed, binding_text(report["binding"][name]))
            for name, speed in report["predicted_max_speed"].items() if speed is not None]
    return rows + [(label, report[key], "") for key, label in SIMULATED.items() if key in report]


def max_speed_figure(report: dict, subject: str):
    """The figure of the module docstring of ``report`` (``max-speed``'s JSON); ``subject`` names
    the robot and its tool."""
    shown = bars(report)
    fig, ax = plt.subplots(figsize=(7.6, 0.5 * len(shown) + 1.6))
    labels = [label for label, _, _ in shown]
    speeds = [speed for _, speed, _ in shown]
    colors = ["tab:blue" if note else "tab:gray" for _, _, note in shown]
    ax.barh(labels, speeds, color=colors)
    for k, (_, speed, note) in enumerate(shown):
        ax.text(speed, k, f" {speed:.3f} m/s" + (f", binds: {note}" if note else ""), va="center", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0.0, 1.8 * max(speeds))
    ax.set_xlabel("highest feasible contact speed (m/s)")
    robust = report["predicted_max_speed"].get("robust")
    verdict = "" if robust is None else f", {robust:.3f} m/s for every predictor (robust)"
    ax.set_title(f"{subject} at {report['posture']}: highest feasible contact speed{verdict}", fontsize=9)
    fig.tight_layout()
    return fig


def write_max_speed_figure(report: dict, subject: str, path: str | Path) -> Path:
    """Write :func:`max_speed_figure` to ``path`` (format by suffix), atomically."""
    path = check_figure_suffix(path)
    return save_figure(max_speed_figure(report, subject), path)
