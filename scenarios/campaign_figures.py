"""The PNG figures of a fixed-base arm's campaign (``scenarios.campaign``, after the paper's
Figs. 4 and 8-12): per posture, the simulated jump of every joint against the normal speed, the
absolute error |e_i| of every predictor of Table I per joint, each kind on one y scale for all
postures, and per joint each predictor's jump against the simulated one (the diagonal is a
perfect prediction); for the tangential series, the average error of every predictor against
v_t. Every title names the robot and its tool (the figures' ``subject``) and the speeds; a speed
axis starts at 0, so that a campaign of one speed shows one point at its speed, not the middle
of an axis a few mm/s wide.
"""

from __future__ import annotations

from pathlib import Path
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.jump import METHODS  # noqa: E402

SCATTER_METHODS = ("crb", "gm", "classical")
SCATTER_MARKERS = {"crb": ("tab:green", "o"), "gm": ("tab:orange", "s"), "classical": ("tab:purple", "^")}


class CampaignFigures:
    """The PNG figures of the module docstring. Each point is one simulated trial (one per
    setting, the simulation is deterministic); the figures of the postures share their y scale so
    that they compare, and the error panels show every predictor of Table I. ``table`` is an arm's
    ``scenarios.campaign.Table1`` (its ``rows``, each a ``TableRow``), ``subject`` what the titles
    name first (the robot and its tool, e.g. "panda with impact_tip")."""

    def __init__(self, table, subject: str = ""):
        self.table = table
        self.subject = subject

    def title(self, what: str, rows: list) -> str:
        """``what``, preceded by the subject, followed by the normal speeds of ``rows``."""
        speeds = sorted({r.normal_speed for r in rows})
        span = f"{speeds[0]:g} m/s" if len(speeds) == 1 else f"{speeds[0]:g}-{speeds[-1]:g} m/s ({len(speeds)} speeds)"
        return f"{self.subject + ': ' if self.subject else ''}{what}, v_n {span}"

    def write(self, out: Path) -> list[Path]:
        paths = []
        normal_rows = [r for r in self.table.rows if r.tangential_speed == 0.0]
        jump_limits = y_limits([r.measured_jump for r in normal_rows])
        error_limits = y_limits([r.joint_errors[m] for r in normal_rows for m in METHODS], zero=True)
        for posture in dict.fromkeys(r.posture for r in normal_rows):
            rows = sorted((r for r in normal_rows if r.posture == posture), key=lambda r: r.normal_speed)
            jumps = self.jumps_figure(posture, rows, jump_limits)
            paths.append(save_figure(jumps, out / f"jumps_{posture}.png"))
            paths.append(save_figure(self.errors_figure(posture, rows, error_limits), out / f"errors_{posture}.png"))
            if all(r.predicted_jump for r in rows):
                paths.append(save_figure(self.predictions_figure(posture, rows), out / f"predicted_{posture}.png"))
        tangential = sorted((r for r in self.table.rows if r.tangential_speed > 0.0), key=lambda r: r.tangential_speed)
        if tangential:
            paths.append(save_figure(self.tangential_figure(tangential), out / "tangential.png"))
        return paths

    def jumps_figure(self, posture: str, rows: list, ylim: tuple[float, float] | None = None):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.normal_speed for r in rows]
        jumps = np.array([r.measured_jump for r in rows])
        for j in range(jumps.shape[1]):
            ax.plot(speeds, jumps[:, j], "o-", label=f"joint {j + 1}")
        ax.set(
            xlabel="normal contact speed (m/s)", ylabel="simulated jump dq+ - dq- (rad/s)",
            title=self.title(f"simulated joint-velocity jumps at {posture}", rows)
            + "\n(one trial per speed, no tangential velocity)",
        )
        ax.title.set_fontsize(9)
        ax.set_xlim(speed_limits(speeds))
        if ylim is not None:
            ax.set_ylim(ylim)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        return fig

    def errors_figure(self, posture: str, rows: list, ylim: tuple[float, float] | None = None):
        fig, axes = plt.subplots(1, len(METHODS), figsize=(3.6 * len(METHODS), 4.0), sharey=True)
        speeds = [r.normal_speed for r in rows]
        for ax, method in zip(axes, METHODS):
            errors = np.array([r.joint_errors[method] for r in rows])
            for j in range(errors.shape[1]):
                ax.plot(speeds, errors[:, j], "o-", label=f"joint {j + 1}")
            ax.set(title=method, xlabel="normal contact speed (m/s)", ylabel="|e_i|, eq. (25) (rad/s)")
            ax.set_xlim(speed_limits(speeds))
            ax.yaxis.set_tick_params(labelleft=True)
        if ylim is not None:
            axes[0].set_ylim(ylim)
        axes[-1].legend(fontsize=7, ncol=2)
        fig.suptitle(
            self.title(f"absolute prediction error per joint at {posture}", rows)
            + "\n(each predictor's own jump against the simulated one, one trial per speed)", fontsize=10,
        )
        fig.tight_layout()
        return fig

    def predictions_figure(self, posture: str, rows: list):
        """Per joint, each predictor's jump against the simulated one (one point per trial), and
        the diagonal of a perfect prediction; each panel's axes hold its points and 0."""
        joints = len(rows[0].predicted_jump["crb"])
        columns = min(4, joints)
        lines = -(-joints // columns)
        fig, axes = plt.subplots(lines, columns, figsize=(3.0 * columns, 2.8 * lines + 0.9), squeeze=False)
        for j, ax in enumerate(axes.flat[:joints]):
            measured = np.array([r.measured_jump[-joints:][j] for r in rows])
            values = [measured, np.zeros(1)]
            for method in SCATTER_METHODS:
                predicted = np.array([r.predicted_jump[method][j] for r in rows])
                color, marker = SCATTER_MARKERS[method]
                ax.plot(measured, predicted, marker, color=color, ls="none", ms=5, label=method)
                values.append(predicted)
            low, high = y_limits(values)
            ax.plot([low, high], [low, high], color="0.5", lw=0.8, label="predicted = simulated")
            ax.set(xlim=(low, high), ylim=(low, high), title=f"joint {j + 1}")
            ax.set_xlabel("simulated jump (rad/s)", fontsize=8)
            ax.set_ylabel("predicted jump (rad/s)", fontsize=8)
            ax.tick_params(labelsize=7)
        for ax in axes.flat[joints:]:
            ax.set_visible(False)
        axes.flat[0].legend(fontsize=6)
        fig.suptitle(self.title(f"predicted against simulated jumps per joint at {posture}", rows), fontsize=10)
        fig.tight_layout()
        return fig

    def tangential_figure(self, rows: list):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.tangential_speed for r in rows]
        for method in METHODS:
            ax.plot(speeds, [r.errors[method] for r in rows], "o-", label=method)
        ax.set(
            xlabel="tangential speed v_t (m/s)", ylabel="average prediction error, eq. (26) (rad/s)",
            title=self.title(f"tangential series at {rows[0].posture}", rows)
            + f"\n(error averaged over the {len(rows[0].measured_jump)} joints, one trial per v_t)",
        )
        ax.title.set_fontsize(9)
        ax.set_xlim(speed_limits(speeds))
        ax.set_ylim(bottom=0.0)
        ax.legend()
        fig.tight_layout()
        return fig


def y_limits(values: list[np.ndarray], zero: bool = False) -> tuple[float, float] | None:
    """A y range that holds every value (and 0 when ``zero``), with a 5 % margin; None without
    values."""
    if not values:
        return None
    data = np.concatenate([np.ravel(v) for v in values] + ([np.zeros(1)] if zero else []))
    low, high = float(data.min()), float(data.max())
    margin = 0.05 * (high - low) or 0.05
    return (0.0 if zero else low - margin, high + margin)


def speed_limits(speeds: list[float]) -> tuple[float, float]:
    """A speed axis from 0 to 15 % beyond the largest speed."""
    return 0.0, 1.15 * max(speeds)


def save_figure(fig, path: Path) -> Path:
    """Save a figure atomically (``controller.measured.atomic.write_atomic``) in the format of the
    path's suffix (PNG, PDF or SVG) and close it."""
    path = Path(path)
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=100, format=path.suffix[1:].lower()))
    finally:
        plt.close(fig)
