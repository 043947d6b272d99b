"""The figure of one simulated impact: every joint's velocity dq_i(t) around the contact, from
:data:`BEFORE_MS` before it to :data:`AFTER_MS` after it (ms, t = 0 at the contact), beside the
post-impact velocity each predictor foresees, dq+ = dq- + Delta dq (eq. (19): the CRB, the
generalized-momentum and the classical predictions, drawn from the contact on) and the velocity
limits +-dq_max of the robot's description. A robot with more than :data:`MAX_PANELS` joints
shows the joints whose predicted |dq+_i| / dq_max_i (CRB) is largest.

A limit far beyond the velocities (a slow impact) would flatten every curve: each panel's y
range holds the velocities, the predictions and the limits when the limits are within
:data:`LIMIT_IN_VIEW` times the largest velocity; otherwise the limit lines stay drawn outside
the range and the panel says "limit +-X off scale". The title names the robot, the tool, the
posture and the speeds. Written atomically (``scenarios.campaign_figures.save_figure``).
Matplotlib (1 s to import) loads only when a figure is drawn: a trial's command imports this
module for its labels and its suffix check.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.model.validation import BadInputError

BEFORE_MS = 30.0
AFTER_MS = 60.0
MAX_PANELS = 8
LIMIT_IN_VIEW = 3.0
PREDICTORS = ("crb", "gm", "classical")
PREDICTOR_STYLE = {"crb": ("tab:green", "--"), "gm": ("tab:orange", "-."), "classical": ("tab:purple", ":")}
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


@dataclass(frozen=True)
class ImpactLabel:
    """What a picture of a trial names: the ``robot`` (its description: joint names, limits),
    the ``tool``'s name and the ``posture``."""

    robot: object
    tool: str
    posture: str


def check_figure_suffix(path: str | Path, what: str = "--figure") -> Path:
    """``path`` when its suffix is a format of :data:`FIGURE_SUFFIXES`, else bad input."""
    path = Path(path)
    if path.suffix.lower() not in FIGURE_SUFFIXES:
        raise BadInputError(f"{what} writes a figure: give a {', '.join(FIGURE_SUFFIXES)} file name, got {str(path)!r}")
    return path


def post_velocities(trial) -> dict[str, np.ndarray]:
    """The joints' predicted dq+ = dq- + Delta dq (``TrialResult.predicted_post_velocity``) of
    every predictor of :data:`PREDICTORS` the trial has."""
    return {m: trial.predicted_post_velocity(m) for m in PREDICTORS if m in trial.predicted}


def shown_joints(trial, dq_max: np.ndarray) -> list[int]:
    """Every joint, or the :data:`MAX_PANELS` of largest predicted |dq+_i| / dq_max_i (CRB)."""
    if len(dq_max) <= MAX_PANELS:
        return list(range(len(dq_max)))
    ratio = np.abs(post_velocities(trial)["crb"]) / dq_max
    return sorted(np.argsort(-ratio)[:MAX_PANELS].tolist())


def velocity_figure(trial, label: ImpactLabel):
    """The figure of the module docstring for ``trial`` (``sim.trial_result.TrialResult``)."""
    from .campaign_figures import plt

    robot = label.robot
    t_ms = (trial.log.t - trial.impact.t_contact_start) * 1e3
    window = (t_ms >= -BEFORE_MS) & (t_ms <= AFTER_MS)
    post = post_velocities(trial)
    joints = shown_joints(trial, robot.dq_max)
    columns = min(4, len(joints))
    rows = -(-len(joints) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 2.6 * rows + 0.9), squeeze=False)
    for ax, j in zip(axes.flat, joints):
        dq = trial.log.dq[window, j]
        ax.plot(t_ms[window], dq, color="tab:blue", lw=1.4, label="simulated dq")
        for method, value in post.items():
            color, style = PREDICTOR_STYLE[method]
            ax.plot([0.0, AFTER_MS], [value[j]] * 2, color=color, ls=style, lw=1.2, label=f"{method} dq+")
        limit = float(robot.dq_max[j])
        ax.axhline(limit, color="tab:red", lw=1.0, label="+-dq_max")
        ax.axhline(-limit, color="tab:red", lw=1.0)
        ax.axvline(0.0, color="0.6", lw=0.8)
        values = np.concatenate([dq, [v[j] for v in post.values()]])
        ax.set_ylim(_y_range(values, limit))
        if limit > ax.get_ylim()[1]:
            ax.text(0.98, 0.04, f"limit +-{limit:g} off scale", transform=ax.transAxes, ha="right", fontsize=7)
        ax.set_title(robot.joints[j], fontsize=9)
        ax.set_xlabel("t - t_contact (ms)", fontsize=8)
        ax.set_ylabel("dq (rad/s)", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(joints):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=6, loc="best")
    fig.suptitle(
        f"{robot.name} with {label.tool} at {label.posture}: joint velocities around the impact, "
        f"contact speed {trial.contact_speed:.3f} m/s (commanded {trial.normal_speed:g} m/s)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def _y_range(values: np.ndarray, limit: float) -> tuple[float, float]:
    """The values' range with a 10 % margin, widened to +-``limit`` when the limit is within
    LIMIT_IN_VIEW times the largest |value|."""
    low, high = float(values.min()), float(values.max())
    if limit <= LIMIT_IN_VIEW * max(abs(low), abs(high)):
        low, high = min(low, -limit), max(high, limit)
    margin = 0.1 * (high - low) or 0.05
    return low - margin, high + margin


def write_velocity_figure(trial, label: ImpactLabel, path: str | Path) -> Path:
    """Write :func:`velocity_figure` to ``path`` (format by suffix), atomically."""
    from .campaign_figures import save_figure

    path = check_figure_suffix(path)
    return save_figure(velocity_figure(trial, label), path)
