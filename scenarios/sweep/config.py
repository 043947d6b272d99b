"""The sweep configuration (TOML): a rectangle of contact points on a plane and the settings to vary.

The grid is the product points x normals x restitution values x the controller settings
(impact durations x controller jump models), and with the optional ``[friction]`` table x
frictions mu x tangential speeds; every cell evaluates all the listed jump models in closed
form (with ``[friction]`` also under the robust friction rows, docs/sweep.md). Every key is checked before any work starts: an unknown key, a malformed value, an
empty grid, a spacing <= 0, a value out of its range or a value listed twice (two normals of one
direction included) raises :class:`BadInputError` (docs/sweep.md).
"""

from __future__ import annotations

import math

import json
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from impactqp.controller.model.friction_pyramid import DEFAULT_EDGES, FrictionRows
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.robot_description import PANDA
from impactqp.constraints import JUMP_MODEL_CHOICES
from impactqp.controller.model.files import read_mapping
from impactqp.controller.model.validation import (
    BadInputError,
    finite_vector,
    impact_duration,
    non_empty_list,
    number_in_range,
    positive,
    restitution,
    unit_normal,
)

EXAMPLE = """\
# impactqp sweep: a feasibility map of the highest safe contact speed (docs/sweep.md).
# Every list below is an axis of the grid; a cell is one combination of their values.

[grid]
# A corner of the rectangle of contact points (m, world frame).
origin = [0.6, -0.2, 0.5]
# The two edge directions of the rectangle (normalised; need not be unit length here).
u = [0.0, 1.0, 0.0]
v = [0.0, 0.0, 1.0]
# Edge lengths along u and v (m), >= 0.
size = [0.4, 0.3]
# Distance between neighbouring points along u and v (m), > 0.
spacing = 0.1

[settings]
# Surface normals, pointing towards the robot; the tool axis is placed along -n.
normals = [[-1.0, 0.0, 0.0]]
# Coefficients of restitution in [0, 1] (the closed form's and the controller's c_r).
restitution = [0.0]
# Jump models of the closed form, evaluated in every cell: classical, classical_normal, gm, crb.
jump_models = ["gm", "crb"]
# Seed posture of the inverse kinematics, the same for every cell: a named posture (impactqp postures).
seed_posture = "elbow_up"

[controller]
# Jump-aware constraints of the controller in the simulated QP-limited run (--simulate):
# crb, gm, classical, classical_normal or robust. Closed-form values do not depend on it.
jump_model = ["crb"]
# Impact duration delta_t (s) of the impulsive-torque criterion and constraint, in [0.001, 0.1].
impact_duration = [0.015]

[simulate]
# Bisection tolerance (m/s) of the simulated highest feasible speed (--simulate only), in [0.0001, 0.5].
tolerance = 0.005
"""

GRID_KEYS = {"origin", "u", "v", "size", "spacing"}
SETTINGS_KEYS = {"normals", "restitution", "jump_models", "seed_posture"}
CONTROLLER_KEYS = {"jump_model", "impact_duration"}
SIMULATE_KEYS = {"tolerance"}
TABLES = {"grid": GRID_KEYS, "settings": SETTINGS_KEYS, "controller": CONTROLLER_KEYS, "simulate": SIMULATE_KEYS}
FRICTION_KEYS = {"mu", "tangential_speed", "pyramid_edges"}
"""The optional ``[friction]`` table: the rows' mu and the sliding speeds (axes), the pyramid's edges."""
MAX_TANGENTIAL_SPEED = 2.0
"""m/s: the largest tangential speed of a friction sweep (the QP's request speed, ``max-speed``)."""
MAX_CELLS = 10_000_000
NORMAL_DECIMALS = 9
"""Two of ``settings.normals`` whose unit vectors agree in every component to this many decimals
are one direction (listed twice): they differ by rounding only."""


@dataclass(frozen=True)
class SweepConfig:
    origin: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]
    size: tuple[float, float]
    spacing: float
    normals: tuple[tuple[float, float, float], ...]
    restitution: tuple[float, ...]
    jump_models: tuple[str, ...]
    seed_posture: str
    controller_jump_model: tuple[str, ...]
    impact_duration: tuple[float, ...]
    tolerance: float
    friction: tuple[float, ...] = ()
    """mu of the robust friction rows (``[friction]``; empty: no friction axes nor columns)."""
    tangential_speed: tuple[float, ...] = ()
    """m/s: the contact's sliding speed along the surface tangent t = normalise(n x e_z)."""
    pyramid_edges: int = DEFAULT_EDGES
    choice: RobotChoice = field(default=DEFAULT_CHOICE, compare=False)
    """The robot and the tool (``--robot``, ``--tool``), not a key of the file."""

    def canonical_json(self) -> str:
        """The configuration as sorted JSON: two configs are the same sweep when this is equal
        (the robot and the tool count when they are not the default Panda and impact tip)."""
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "choice"}
        if not self.friction:  # a sweep without [friction] keeps its identity
            data = {name: value for name, value in data.items() if name not in FRICTION_FIELDS}
        if not self.choice.is_default:
            data |= {"robot": self.choice.robot.name, "tool": self.choice.tool.as_dict()}
        return json.dumps(data, sort_keys=True)

    @property
    def seed(self) -> np.ndarray:
        """The seed posture's joint positions, for the robot and the tool."""
        return self.choice.posture(self.seed_posture).q.copy()

    def points(self) -> np.ndarray:
        """The contact points (P, 3): origin + i spacing u + j spacing v, row-major in (i, j)."""
        u = np.asarray(self.u) / np.linalg.norm(self.u)
        v = np.asarray(self.v) / np.linalg.norm(self.v)
        nu, nv = self.grid_shape()
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        return (
            np.asarray(self.origin)
            + (i.ravel()[:, None] * self.spacing) * u
            + (j.ravel()[:, None] * self.spacing) * v
        )

    def grid_shape(self) -> tuple[int, int]:
        """Points along u and along v."""
        return tuple(int(np.floor(size / self.spacing + 1e-9)) + 1 for size in self.size)

    def axes_shape(self) -> tuple[int, ...]:
        """Lengths of the axes (points, normals, restitution, impact_duration, controller
        jump model, friction, tangential speed; the last two 1 without ``[friction]``), slowest
        first: the cell index is their row-major (C-order) index."""
        nu, nv = self.grid_shape()
        return (
            nu * nv, len(self.normals), len(self.restitution), len(self.impact_duration),
            len(self.controller_jump_model), len(self.friction) or 1, len(self.tangential_speed) or 1,
        )

    def cell_count(self) -> int:
        return int(np.prod(self.axes_shape()))

    def cell_axes(self, cells: np.ndarray) -> tuple[np.ndarray, ...]:
        """Axis indices (point, normal, restitution, impact_duration, controller jump model,
        friction, tangential speed) of the cell indices ``cells``."""
        return np.unravel_index(np.asarray(cells), self.axes_shape())


FRICTION_FIELDS = ("friction", "tangential_speed", "pyramid_edges")


def _table(data: dict, name: str, keys: set[str]) -> dict:
    table = data.get(name)
    if not isinstance(table, dict):
        raise BadInputError(f"the sweep config needs a [{name}] table")
    unknown = sorted(set(table) - keys)
    if unknown:
        raise BadInputError(f"unknown key {name}.{unknown[0]} in the sweep config")
    missing = sorted(keys - set(table))
    if missing:
        raise BadInputError(f"missing key {name}.{missing[0]} in the sweep config")
    return table


def parse_config(data: dict) -> SweepConfig:
    """A validated :class:`SweepConfig` from the parsed TOML ``data``."""
    unknown = sorted(set(data) - set(TABLES) - {"friction"})
    if unknown:
        raise BadInputError(f"unknown key {unknown[0]} in the sweep config")
    grid, settings, controller, simulate = (_table(data, name, keys) for name, keys in TABLES.items())
    origin = finite_vector(grid["origin"], 3, "grid.origin")
    u = unit_normal(grid["u"], "grid.u")
    v = unit_normal(grid["v"], "grid.v")
    if abs(float(u @ v)) > 1.0 - 1e-6:
        raise BadInputError(f"grid.u {u.tolist()} and grid.v {v.tolist()} are parallel: the grid would be a line")
    size = finite_vector(grid["size"], 2, "grid.size")
    if np.any(size < 0.0):
        raise BadInputError(f"grid.size must be >= 0, got {size.tolist()}")
    spacing = positive(grid["spacing"], "grid.spacing")
    normals = [
        tuple(unit_normal(n, f"settings.normals[{k}]").tolist())
        for k, n in enumerate(non_empty_list(settings["normals"], "settings.normals"))
    ]
    _listed_once("settings.normals", [tuple(round(x, NORMAL_DECIMALS) for x in n) for n in normals],
                 "are one direction (normals are normalised)")
    restitutions = [
        restitution(c, f"settings.restitution[{k}]")
        for k, c in enumerate(non_empty_list(settings["restitution"], "settings.restitution"))
    ]
    _listed_once("settings.restitution", restitutions)
    models = non_empty_list(settings["jump_models"], "settings.jump_models")
    for name in models:
        if name not in JUMP_MODELS:
            raise BadInputError(
                f"unknown jump model {name!r} in settings.jump_models; choose from {', '.join(JUMP_MODELS)}"
            )
    _listed_once("settings.jump_models", models)
    seed = settings["seed_posture"]
    if seed not in PANDA.postures:
        raise BadInputError(
            f"unknown settings.seed_posture {seed!r}; choose from {', '.join(PANDA.postures)}"
        )
    controller_models = non_empty_list(controller["jump_model"], "controller.jump_model")
    for name in controller_models:
        if name not in JUMP_MODEL_CHOICES:
            raise BadInputError(
                f"unknown jump model {name!r} in controller.jump_model; choose from {', '.join(JUMP_MODEL_CHOICES)}"
            )
    durations = [
        impact_duration(value, f"controller.impact_duration[{k}]")
        for k, value in enumerate(non_empty_list(controller["impact_duration"], "controller.impact_duration"))
    ]
    _listed_once("controller.jump_model", controller_models)
    _listed_once("controller.impact_duration", durations)
    config = SweepConfig(
        origin=tuple(origin.tolist()),
        u=tuple(u.tolist()),
        v=tuple(v.tolist()),
        size=tuple(size.tolist()),
        spacing=spacing,
        normals=tuple(normals),
        restitution=tuple(restitutions),
        jump_models=tuple(models),
        seed_posture=seed,
        controller_jump_model=tuple(controller_models),
        impact_duration=tuple(durations),
        tolerance=_bisection_tolerance(simulate["tolerance"]),
        **(_friction(_table(data, "friction", FRICTION_KEYS), models) if "friction" in data else {}),
    )
    points = [math.floor(side / spacing + 1e-9) + 1 if side / spacing < MAX_CELLS else MAX_CELLS + 1 for side in size.tolist()]
    settings_count = math.prod((len(normals), len(restitutions), len(durations), len(controller_models),
                                len(config.friction) or 1, len(config.tangential_speed) or 1))
    cells = math.prod(points) * settings_count
    if cells > MAX_CELLS:
        shown = " x ".join(str(p) if p <= MAX_CELLS else f"over {MAX_CELLS:,}" for p in points)
        raise BadInputError(
            f"the sweep has {cells:.3g} cells ({shown} points x {settings_count} settings), more than "
            f"{MAX_CELLS:,}: make grid.spacing coarser or the grid smaller"
        )
    return config


def _listed_once(key: str, values: list, same: str = "are equal") -> None:
    """Refuse (naming ``key`` and the two entries) a list of the config that holds a value twice;
    values compare as Python numbers and strings do (0.0 and -0.0 are one value)."""
    first: dict = {}
    for k, value in enumerate(values):
        if value in first:
            raise BadInputError(f"{key} lists a value twice: {key}[{first[value]}] and {key}[{k}] {same}")
        first[value] = k


def _bisection_tolerance(value) -> float:
    """``simulate.tolerance``, checked as ``max-speed --tolerance`` (``max_speed_search``, whose
    bisection takes it)."""
    from impactqp.scenarios.max_speed_search import bisection_tolerance  # loads the simulation: not at import

    return bisection_tolerance(value, "simulate.tolerance")


def _friction(table: dict, models: list) -> dict:
    """The checked ``[friction]`` table as the config's fields (docs/sweep.md, "Friction")."""
    mus = []
    for k, mu in enumerate(non_empty_list(table["mu"], "friction.mu")):
        try:
            mus.append(FrictionRows(mu, table["pyramid_edges"]).friction)
        except BadInputError as error:
            raise BadInputError(f"friction.mu[{k}] or friction.pyramid_edges: {error}") from None
    speeds = [
        number_in_range(v, 0.0, MAX_TANGENTIAL_SPEED, f"friction.tangential_speed[{k}]", "m/s")
        for k, v in enumerate(non_empty_list(table["tangential_speed"], "friction.tangential_speed"))
    ]
    _listed_once("friction.mu", mus)
    _listed_once("friction.tangential_speed", speeds)
    if "classical_normal" in models:
        raise BadInputError("the classical_normal model keeps the normal impulse only: it has no friction rows "
                            "(settings.jump_models with [friction])")
    return {"friction": tuple(mus), "tangential_speed": tuple(speeds), "pyramid_edges": int(table["pyramid_edges"])}


def load_config(path: Path) -> SweepConfig:
    """Read and validate the TOML file ``path``."""
    return parse_config(read_mapping(path, "the sweep config", "toml"))
