"""The PNG figures of a fixed-base arm's campaign (``scenarios.campaign``, after the paper's
Figs. 8-12): per posture, the simulated jump of every joint against the normal speed and the
absolute error |e_i| of every predictor of Table I per joint, each kind on one y scale for all
postures; for the tangential series, the average error of every predictor against v_t.
"""

from __future__ import annotations

from pathlib import Path
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.jump import METHODS  # noqa: E402


class CampaignFigures:
    """The PNG figures of the module docstring. Each point is one simulated trial (one per
    setting, the simulation is deterministic); the figures of the postures share their y scale so
    that they compare, and the error panels show every predictor of Table I. ``table`` is an arm's
    ``scenarios.campaign.Table1`` (its ``rows``, each a ``TableRow``)."""

    def __init__(self, table):
        self.table = table

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
        tangential = sorted((r for r in self.table.rows if r.tangential_speed > 0.0), key=lambda r: r.tangential_speed)
        if tangential:
            paths.append(save_figure(self.tangential_figure(tangential), out / "tangential.png"))
        return paths

    @staticmethod
    def jumps_figure(posture: str, rows: list, ylim: tuple[float, float] | None = None):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.normal_speed for r in rows]
        jumps = np.array([r.measured_jump for r in rows])
        for j in range(jumps.shape[1]):
            ax.plot(speeds, jumps[:, j], "o-", label=f"joint {j + 1}")
        ax.set(
            xlabel="normal contact speed (m/s)", ylabel="simulated jump dq+ - dq- (rad/s)",
            title=f"Simulated joint-velocity jumps at {posture}\n(one trial per speed, no tangential velocity)",
        )
        if ylim is not None:
            ax.set_ylim(ylim)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        return fig

    @staticmethod
    def errors_figure(posture: str, rows: list, ylim: tuple[float, float] | None = None):
        fig, axes = plt.subplots(1, len(METHODS), figsize=(3.6 * len(METHODS), 4.0), sharey=True)
        speeds = [r.normal_speed for r in rows]
        for ax, method in zip(axes, METHODS):
            errors = np.array([r.joint_errors[method] for r in rows])
            for j in range(errors.shape[1]):
                ax.plot(speeds, errors[:, j], "o-", label=f"joint {j + 1}")
            ax.set(title=method, xlabel="normal contact speed (m/s)", ylabel="|e_i|, eq. (25) (rad/s)")
            ax.yaxis.set_tick_params(labelleft=True)
        if ylim is not None:
            axes[0].set_ylim(ylim)
        axes[-1].legend(fontsize=7, ncol=2)
        fig.suptitle(
            f"Absolute prediction error per joint at {posture}: each predictor's own jump against the "
            "simulated one (one trial per speed)", fontsize=10,
        )
        fig.tight_layout()
        return fig

    @staticmethod
    def tangential_figure(rows: list):
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        speeds = [r.tangential_speed for r in rows]
        for method in METHODS:
            ax.plot(speeds, [r.errors[method] for r in rows], "o-", label=method)
        ax.set(
            xlabel="tangential speed v_t (m/s)", ylabel="average prediction error, eq. (26) (rad/s)",
            title=f"Tangential series at {rows[0].posture}, v_n = {rows[0].normal_speed:g} m/s\n"
            f"(error averaged over the {len(rows[0].measured_jump)} joints, one trial per v_t)",
        )
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


def save_figure(fig, path: Path) -> Path:
    """Save a figure atomically (``controller.measured.atomic.write_atomic``) in the format of the
    path's suffix (PNG, PDF or SVG) and close it."""
    path = Path(path)
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=100, format=path.suffix[1:].lower()))
    finally:
        plt.close(fig)
