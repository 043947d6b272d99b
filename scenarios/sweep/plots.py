"""Feasibility-map figures (PNG, matplotlib Agg) of a finished sweep.

For each normal, restitution value and impact duration (a *slice* of the grid):

- ``speed_<slice>.png``: a heat map of the closed-form highest feasible speed (m/s) over the
  contact points for each jump model, on one colour scale, and the difference of the second
  model minus the first on a diverging map centred on zero (``CenteredNorm``); the closed form
  does not depend on the controller's jump model, so the cells of the first one are drawn;
- ``binding_<slice>.png``: the binding criterion (colour) and joint (the number in the cell);
- with ``--simulate``, for each controller jump model C, ``simulated_<slice>_controllerC.png``:
  the simulated highest feasible speed and the QP-limited speed on one colour scale.

``<slice>`` is ``normalK_n<nx>_<ny>_<nz>_restitutionR_durationT``: the indices into the config's
lists and the normal's value. Cells without a value are grey, in shades that the legend names:
unreachable, singular (``controller.model.robot.SINGULAR_RATIO``) and, simulated, no start
posture in front of the surface or no impact. The axes are the grid's u and v (m) from its
origin, whose world coordinates the title gives.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402
from matplotlib.colors import CenteredNorm, ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.model.max_speed import CRITERIA  # noqa: E402

from .config import SweepConfig  # noqa: E402

# Cells without a value: (label, grey), drawn under the heat map.
BLANK_CELLS = (
    ("unreachable", "0.85"),
    ("singular", "0.6"),
    ("no start posture", "0.45"),
    ("no impact", "0.3"),
)
CRITERION_COLOURS = ("#8dd3c7", "#fdb462", "#bebada")  # light: the joint numbers stay readable
DPI = 90


def vector_text(values) -> str:
    """``[0.6, -0.2, 0.5]``: 4 significant digits, no ``-0``."""
    return "[" + ", ".join(f"{float(x) + 0.0:.4g}" for x in values) + "]"


def normal_tag(normal) -> str:
    """The normal's value in a file name: ``-1_0_0``."""
    return "_".join(f"{float(x) + 0.0:.4g}" for x in normal)


@dataclass(frozen=True)
class Slice:
    """The cells of one normal K, restitution R, impact duration T and controller jump model C (and
    of a friction sweep the first mu and tangential speed: the drawn columns do not depend on them)."""

    config: SweepConfig
    columns: dict
    k: int
    r: int
    t: int
    c: int = 0

    @property
    def cells(self) -> np.ndarray:
        return np.arange(self.config.cell_count()).reshape(self.config.axes_shape())[:, self.k, self.r, self.t, self.c, 0, 0]

    def grid(self, name: str, dtype=float) -> np.ndarray:
        """Column ``name`` as a (v, u) image: row i is the i-th point along v."""
        nu, nv = self.config.grid_shape()
        return np.asarray(self.columns[name], dtype=dtype)[self.cells].reshape(nu, nv).T

    def blank(self) -> np.ndarray:
        """Index into BLANK_CELLS of each cell without a value (NaN where it has one)."""
        code = np.full(self.grid("cell").shape, np.nan)
        code[self.grid("singular", bool)] = 1
        code[~self.grid("reachable", bool)] = 0
        if "simulated_status" in self.columns:
            status = self.grid("simulated_status", object)
            code[status == "no_start"] = 2
            code[status == "no_impact"] = 3
        return code

    @property
    def extent(self) -> list[float]:
        """Image extent: cells centred on their contact points (m from the origin)."""
        nu, nv = self.config.grid_shape()
        h = self.config.spacing / 2.0
        return [-h, (nu - 1) * self.config.spacing + h, -h, (nv - 1) * self.config.spacing + h]

    def suffix(self) -> str:
        normal = self.config.normals[self.k]
        return f"normal{self.k}_n{normal_tag(normal)}_restitution{self.r}_duration{self.t}"

    def title(self, what: str) -> str:
        config = self.config
        return (
            f"{what}\nnormal n = {vector_text(config.normals[self.k])}, c_r = {config.restitution[self.r]:g}, "
            f"delta_t = {config.impact_duration[self.t]:g} s; grid origin at world {vector_text(config.origin)} m"
        )


def draw_map(ax, piece: Slice, image: np.ndarray, **style):
    """The grey cells without a value, the heat map ``image`` over them, and the axis labels."""
    greys = ListedColormap([grey for _, grey in BLANK_CELLS])
    ax.imshow(piece.blank(), origin="lower", extent=piece.extent, aspect="auto", cmap=greys,
              vmin=-0.5, vmax=len(BLANK_CELLS) - 0.5, interpolation="nearest")
    drawn = ax.imshow(image, origin="lower", extent=piece.extent, aspect="auto", interpolation="nearest", **style)
    config = piece.config
    ax.set_xlabel(f"u (m) along {vector_text(config.u)}")
    ax.set_ylabel(f"v (m) along {vector_text(config.v)}")
    return drawn


def colour_bar(fig, ax, drawn, image: np.ndarray) -> None:
    """A colour bar (m/s) beside ``ax``, unless no cell has a value (it would show a made-up scale)."""
    if np.isfinite(image).any():
        fig.colorbar(drawn, ax=ax, label="m/s")


def blank_legend(fig, piece: Slice, extra: list | None = None) -> None:
    """Legend of the grey cells the figure shows (and ``extra`` handles), under the panels."""
    shown = set(np.unique(piece.blank()[np.isfinite(piece.blank())]).astype(int))
    handles = list(extra or []) + [
        Patch(facecolor=grey, edgecolor="0.2", label=label)
        for code, (label, grey) in enumerate(BLANK_CELLS) if code in shown
    ]
    if handles:
        fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)


def common_range(images: list[np.ndarray]) -> dict:
    """vmin and vmax over the finite values of ``images`` (none when there is none)."""
    values = np.concatenate([image[np.isfinite(image)] for image in images])
    return {"vmin": float(values.min()), "vmax": float(values.max())} if values.size else {}


def finish(fig, piece: Slice, what: str):
    fig.suptitle(piece.title(what), fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return fig


def speed_figure(piece: Slice):
    """The closed-form speed of each jump model and the difference of the first two."""
    models = piece.config.jump_models
    panels = len(models) + (1 if len(models) > 1 else 0)
    fig, axes = plt.subplots(1, panels, figsize=(4.6 * panels, 4.2), squeeze=False)
    images = [piece.grid(f"speed_{name}") for name in models]
    scale = common_range(images)
    for ax, name, image in zip(axes[0], models, images):
        colour_bar(fig, ax, draw_map(ax, piece, image, **scale), image)
        ax.set_title(f"highest feasible speed (m/s), {name}", fontsize=9)
    if len(models) > 1:
        diff = images[1] - images[0]
        norm = CenteredNorm() if np.isfinite(diff).any() else None
        colour_bar(fig, axes[0][-1], draw_map(axes[0][-1], piece, diff, cmap="RdBu_r", norm=norm), diff)
        axes[0][-1].set_title(f"{models[1]} - {models[0]} (m/s)", fontsize=9)
    blank_legend(fig, piece)
    return finish(fig, piece, "Closed-form highest feasible contact speed, one cell per contact point")


def binding_figure(piece: Slice):
    """What binds the closed form of each jump model: criterion (colour) and joint (number)."""
    models = piece.config.jump_models
    config = piece.config
    fig, axes = plt.subplots(1, len(models), figsize=(4.6 * len(models), 4.2), squeeze=False)
    colours = ListedColormap(CRITERION_COLOURS[: len(CRITERIA)])
    for ax, name in zip(axes[0], models):
        criterion = piece.grid(f"criterion_{name}", object)
        code = np.full(criterion.shape, np.nan)
        for index, label in enumerate(CRITERIA):
            code[criterion == label] = index
        draw_map(ax, piece, code, cmap=colours, vmin=-0.5, vmax=len(CRITERIA) - 0.5)
        joint = piece.grid(f"joint_{name}", int)
        for i, j in zip(*np.nonzero(joint)):
            ax.text(j * config.spacing, i * config.spacing, str(joint[i, j]), ha="center", va="center",
                    fontsize=8, fontweight="bold", color="black")
        ax.set_title(f"binding criterion and joint (number), {name}", fontsize=9)
    criteria = [
        Patch(facecolor=colour, edgecolor="0.2", label=label) for label, colour in zip(CRITERIA, CRITERION_COLOURS)
    ]
    blank_legend(fig, piece, criteria)
    return finish(fig, piece, "What binds the closed-form highest feasible speed")


def simulated_figure(piece: Slice):
    """The simulated highest feasible speed and the QP-limited speed of controller model C."""
    controller = piece.config.controller_jump_model[piece.c]
    fig, axes = plt.subplots(1, 2, figsize=(9.2, 4.2), squeeze=False)
    images = [piece.grid("simulated_max_speed"), piece.grid("qp_limited_speed")]
    scale = common_range(images)
    for ax, image, label in zip(
        axes[0], images,
        ("simulated highest feasible speed (m/s)", f"QP-limited speed (m/s), {controller} constraints"),
    ):
        colour_bar(fig, ax, draw_map(ax, piece, image, **scale), image)
        ax.set_title(label, fontsize=9)
    blank_legend(fig, piece)
    return finish(fig, piece, f"Simulated contact speeds, controller jump model {controller}")


def save(fig, path: Path) -> Path:
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=DPI, format="png"))
    finally:
        plt.close(fig)


def write_plots(config: SweepConfig, table: pa.Table, out: Path) -> list[Path]:
    """Write the figures into ``out`` and return their paths."""
    columns = table.to_pydict()
    simulated = "simulated_max_speed" in columns
    out = Path(out)
    paths = []
    for k, r, t in np.ndindex(*config.axes_shape()[1:4]):
        piece = Slice(config, columns, k, r, t)
        paths.append(save(speed_figure(piece), out / f"speed_{piece.suffix()}.png"))
        paths.append(save(binding_figure(piece), out / f"binding_{piece.suffix()}.png"))
        for c in range(len(config.controller_jump_model) if simulated else 0):
            piece = Slice(config, columns, k, r, t, c)
            paths.append(save(simulated_figure(piece), out / f"simulated_{piece.suffix()}_controller{c}.png"))
    return paths
