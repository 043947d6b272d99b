"""Feasibility-map figures (PNG, matplotlib Agg) of a finished sweep.

For each normal, restitution value and impact duration: a heat map of the closed-form highest
feasible speed over the grid of contact points for each jump model, one of the binding criterion
and joint, and the difference between the first two models (the closed form does not depend on
the controller's jump model: the cells of the first one are drawn). With ``--simulate``, also for
each controller jump model: the simulated highest feasible speed and the QP-limited speed.
Unreachable or singular cells are left blank (NaN).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.max_speed import CRITERIA  # noqa: E402

from .config import SweepConfig  # noqa: E402


def write_plots(config: SweepConfig, table: pa.Table, out: Path) -> list[Path]:
    """Write the figures into ``out`` and return their paths."""
    columns = table.to_pydict()
    nu, nv = config.grid_shape()
    shape = config.axes_shape()
    cells = np.arange(config.cell_count()).reshape(shape)
    h = config.spacing / 2.0  # cells centred on their contact points
    extent = [-h, config.size[0] + h, -h, config.size[1] + h]
    paths = []
    for k, r, t in np.ndindex(*shape[1:4]):
        for c in range(shape[4]):
            if c > 0 and "simulated_max_speed" not in columns:
                break
            select = cells[:, k, r, t, c]

            def grid(name, dtype=float):
                return np.asarray(columns[name], dtype=dtype)[select].reshape(nu, nv).T

            title = (f"n = {np.round(config.normals[k], 3).tolist()}, c_r = {config.restitution[r]}, "
                     f"delta_t = {config.impact_duration[t]}")
            suffix = f"normal{k}_restitution{r}_duration{t}"
            if "simulated_max_speed" in columns:
                controller = config.controller_jump_model[c]
                fig, axes = plt.subplots(1, 2, figsize=(8, 3.5), squeeze=False)
                for ax, name, label in zip(
                    axes[0], ("simulated_max_speed", "qp_limited_speed"),
                    ("simulated highest feasible speed", f"QP-limited speed, {controller} constraints"),
                ):
                    image = ax.imshow(grid(name), origin="lower", extent=extent, aspect="auto")
                    fig.colorbar(image, ax=ax, label="m/s")
                    ax.set_title(label, fontsize=9)
                    ax.set_xlabel("u (m)")
                    ax.set_ylabel("v (m)")
                fig.suptitle(title)
                fig.tight_layout()
                path = Path(out) / f"simulated_{suffix}_controller{c}.png"
                fig.savefig(path, dpi=80)
                plt.close(fig)
                paths.append(path)
            if c > 0:
                continue
            models = config.jump_models
            panels = len(models) + (1 if len(models) > 1 else 0)
            fig, axes = plt.subplots(1, panels, figsize=(4 * panels, 3.5), squeeze=False)
            for ax, name in zip(axes[0], models):
                image = ax.imshow(grid(f"speed_{name}"), origin="lower", extent=extent, aspect="auto")
                fig.colorbar(image, ax=ax, label="m/s")
                ax.set_title(f"highest feasible speed, {name}")
            if len(models) > 1:
                diff = grid(f"speed_{models[1]}") - grid(f"speed_{models[0]}")
                image = axes[0][-1].imshow(diff, origin="lower", extent=extent, aspect="auto", cmap="coolwarm")
                fig.colorbar(image, ax=axes[0][-1], label="m/s")
                axes[0][-1].set_title(f"{models[1]} - {models[0]}")
            for ax in axes[0]:
                ax.set_xlabel("u (m)")
                ax.set_ylabel("v (m)")
            fig.suptitle(title)
            fig.tight_layout()
            path = Path(out) / f"speed_{suffix}.png"
            write_atomic(path, lambda tmp, fig=fig: fig.savefig(tmp, dpi=80, format="png"))
            plt.close(fig)
            paths.append(path)

            fig, axes = plt.subplots(1, len(models), figsize=(4 * len(models), 3.5), squeeze=False)
            for ax, name in zip(axes[0], models):
                criterion = np.array(columns[f"criterion_{name}"], dtype=object)[select].reshape(nu, nv).T
                joint = grid(f"joint_{name}", int)
                code = np.full(criterion.shape, np.nan)
                for c, label in enumerate(CRITERIA):
                    code[criterion == label] = c
                ax.imshow(code, origin="lower", extent=extent, aspect="auto", vmin=0, vmax=len(CRITERIA) - 1,
                          cmap="viridis")
                du, dv = config.spacing, config.spacing
                for i in range(nv):
                    for j in range(nu):
                        if joint[i, j]:
                            ax.text(j * du, i * dv, str(joint[i, j]), ha="center", va="center", fontsize=7,
                                    color="black")
                ax.set_title(f"binding criterion and joint, {name}")
                ax.set_xlabel("u (m)")
                ax.set_ylabel("v (m)")
            handles = [plt.Rectangle((0, 0), 1, 1, color=plt.cm.viridis(c / (len(CRITERIA) - 1)))
                       for c in range(len(CRITERIA))]
            fig.legend(handles, CRITERIA, loc="lower center", ncol=len(CRITERIA), fontsize=7)
            fig.tight_layout(rect=(0, 0.08, 1, 1))
            path = Path(out) / f"binding_{suffix}.png"
            write_atomic(path, lambda tmp, fig=fig: fig.savefig(tmp, dpi=80, format="png"))
            plt.close(fig)
            paths.append(path)
    return paths
