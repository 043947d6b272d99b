"""Evaluation of sweep cells: contact posture by inverse kinematics, conditioning, closed form,
and with ``--simulate`` the simulated highest feasible speed.

A cell is (point, normal, restitution, impact duration, controller jump model, and with a
``[friction]`` table friction mu and tangential speed). The cells of a chunk are evaluated
together, on the vectorised kinematics of ``controller.model.batch``:

1. the contact posture of every distinct (point, normal) of the chunk, by the batched damped
   least squares of :func:`controller.model.inverse_kinematics.contact_postures` from the
   config's seed posture (the same for every cell);
2. at the reachable postures, cond(M) and the contact Jacobian's singular-value ratio
   sigma_min / sigma_max; a ratio below ``SINGULAR_RATIO`` marks the posture singular, as
   ``PandaModel.terms`` does;
3. for every jump model, the closed-form highest feasible speed and what binds it
   (:func:`controller.model.max_speed.closed_form_max_speeds`, at each restitution and impact
   duration of the chunk); with ``[friction]``, also under the robust friction rows of the cell's
   mu while the contact slides at its tangential speed along t = normalise(n x e_z)
   (:func:`controller.model.friction_max_speed.frictional_max_speed`, one cell at a time);
4. with a :class:`Simulation`, one ``max-speed`` search per cell
   (:class:`scenarios.max_speed_search.MaxSpeedSearch` at the cell's posture, on the plane through
   its point with its normal, with the plant, the cell's restitution, impact duration and
   controller jump model, and the config's tolerance): ``simulated_max_speed`` (the bisection,
   jump-aware constraints off, so it depends on the posture, the surface and the plant only)
   and ``qp_limited_speed`` (the speed the QP reaches with the controller's jump-aware
   constraints on).

An unreachable or singular cell keeps its row, with NaN speeds, an empty criterion and joint 0.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from impactqp.controller.measured.impact import ImpactNotFoundError
from impactqp.controller.model.batch import BatchKinematics
from impactqp.controller.model.inverse_kinematics import UnreachableStartError, contact_postures
from impactqp.controller.model.friction_pyramid import FrictionRows
from impactqp.controller.model.friction_max_speed import frictional_max_speed
from impactqp.controller.model.max_speed import CRITERIA, Setting, approach_directions, closed_form_max_speeds
from impactqp.controller.model.postures import DEFAULT_WALL, ImpactPosture, Surface
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.robot import SINGULAR_RATIO
from impactqp.scenarios.max_speed_search import MaxSpeedSearch, QpSetting
from impactqp.sim.generation import tangential_direction
from impactqp.sim.plant import PlantParameters

from .config import SweepConfig

_KINEMATICS: dict[str, BatchKinematics] = {}

SIMULATED_STATUS = ("simulated", "unreachable", "no_start", "no_impact")
"""``simulated_status``: searched; unreachable or singular posture (not searched); no start
posture in front of the surface (``inverse_kinematics.approach_start``); no impact in a trial."""


@dataclass(frozen=True)
class Simulation:
    """``--simulate``: search the simulated highest feasible speed of every cell on ``plant``
    (None: the nominal plant)."""

    plant: PlantParameters | None = None


def _kinematics(choice: RobotChoice) -> BatchKinematics:
    """One Pinocchio model of the robot and the tool and its batch kinematics per process
    (workers build theirs once)."""
    key = json.dumps([choice.robot.name, choice.tool.as_dict()])
    if key not in _KINEMATICS:
        _KINEMATICS[key] = BatchKinematics(choice.model())
    return _KINEMATICS[key]


def cell_settings(config: SweepConfig, cell: int) -> dict:
    """The settings of cell index ``cell`` (the row-major order of ``SweepConfig.axes_shape``)."""
    p, k, r, t, c, f, g = (int(i) for i in config.cell_axes(cell))
    settings = {
        "point": config.points()[p],
        "normal": np.asarray(config.normals[k]),
        "restitution": config.restitution[r],
        "impact_duration": config.impact_duration[t],
        "controller_jump_model": config.controller_jump_model[c],
    }
    if config.friction:
        settings |= {"friction": config.friction[f], "tangential_speed": config.tangential_speed[g]}
    return settings


@dataclass(frozen=True)
class ClosedFormCells:
    """The chunk's cells as the closed form needs them: the terms of the reached postures, which
    postures are reached and regular, the (point, normal) pairs, each cell's posture and its
    restitution and impact-duration indices."""

    terms: object
    reached: np.ndarray
    regular: np.ndarray
    pairs: np.ndarray
    posture_of_cell: np.ndarray
    r: np.ndarray
    t: np.ndarray


def _closed_forms(config: SweepConfig, cells: ClosedFormCells) -> dict[str, list]:
    """The closed-form speed, criterion and joint columns of every jump model of ``config``."""
    robot = _kinematics(config.choice).robot
    normals = np.asarray(config.normals, dtype=float)
    restitution = np.asarray(config.restitution)
    impact_duration = np.asarray(config.impact_duration)
    r, t, terms, reached = cells.r, cells.t, cells.terms, cells.reached
    n_cells = cells.posture_of_cell.size
    regular_in_reached = cells.regular[reached]
    regular_terms = None
    if terms is not None and regular_in_reached.any():
        regular_terms = terms.rows(regular_in_reached)
    regular_index = np.full(len(cells.pairs), -1)
    regular_index[reached[regular_in_reached]] = np.arange(int(regular_in_reached.sum()))
    cell_regular = regular_index[cells.posture_of_cell]
    if regular_terms is not None:
        regular_normals = normals[cells.pairs[regular_index >= 0, 1]]
        directions = approach_directions(regular_terms, regular_normals)
    columns = {}
    for name in config.jump_models:
        speed = np.full(n_cells, np.nan)
        criterion = np.full(n_cells, -1)
        joint = np.zeros(n_cells, dtype=np.int64)
        if regular_terms is not None:
            for ri, ti in sorted(set(zip(r.tolist(), t.tolist()))):
                select = (r == ri) & (t == ti) & (cell_regular >= 0)
                if not select.any():
                    continue
                best = closed_form_max_speeds(
                    robot, regular_terms, regular_normals, name, float(restitution[ri]), float(impact_duration[ti]),
                    directions,
                )
                rows = cell_regular[select]
                speed[select], criterion[select], joint[select] = (
                    best.speed[rows], best.criterion[rows], best.joint[rows]
                )
        columns[f"speed_{name}"] = speed
        columns[f"criterion_{name}"] = [CRITERIA[i] if i >= 0 else "" for i in criterion]
        columns[f"joint_{name}"] = joint

    return columns


def evaluate_cells(config: SweepConfig, cells: range, simulation: Simulation | None = None) -> dict[str, list]:
    """The columns of the rows of ``cells`` (a contiguous range of cell indices), in order."""
    kinematics = _kinematics(config.choice)
    cell = np.arange(cells.start, cells.stop)
    p, k, r, t, c, f, g = config.cell_axes(cell)
    points = config.points()
    normals = np.asarray(config.normals, dtype=float)
    restitution = np.asarray(config.restitution)
    impact_duration = np.asarray(config.impact_duration)

    # 1. one posture per distinct (point, normal)
    pairs, posture_of_cell = np.unique(np.stack([p, k], axis=1), axis=0, return_inverse=True)
    posture_of_cell = posture_of_cell.ravel()
    solved = contact_postures(kinematics, points[pairs[:, 0]], normals[pairs[:, 1]], config.seed)

    # 2. conditioning of the reachable postures
    n_pairs = len(pairs)
    cond_M = np.full(n_pairs, np.nan)
    sv_ratio = np.full(n_pairs, np.nan)
    reached = np.flatnonzero(solved.reachable)
    terms = kinematics.terms(solved.q[reached]) if reached.size else None
    if terms is not None:
        eigenvalues = np.linalg.eigvalsh(terms.M)  # M is symmetric positive definite
        cond_M[reached] = eigenvalues[:, -1] / eigenvalues[:, 0]
        s = np.linalg.svd(terms.J, compute_uv=False)
        sv_ratio[reached] = s[:, -1] / s[:, 0]
    singular = solved.reachable & ~(sv_ratio >= SINGULAR_RATIO)
    regular = solved.reachable & ~singular  # postures with a closed form

    columns = {
        "cell": cell,
        "point_x": points[p, 0], "point_y": points[p, 1], "point_z": points[p, 2],
        "normal_x": normals[k, 0], "normal_y": normals[k, 1], "normal_z": normals[k, 2],
        "restitution": restitution[r],
        "impact_duration": impact_duration[t],
        "controller_jump_model": [config.controller_jump_model[i] for i in c],
        "reachable": solved.reachable[posture_of_cell],
        "singular": singular[posture_of_cell],
        "position_error": solved.position_error[posture_of_cell],
        "axis_error": solved.axis_error[posture_of_cell],
    }
    q = solved.q[posture_of_cell]
    for j in range(q.shape[1]):
        columns[f"q{j + 1}"] = q[:, j]
    columns["cond_M"] = cond_M[posture_of_cell]
    columns["jacobian_sv_ratio"] = sv_ratio[posture_of_cell]

    # 3. closed form of every model, for each (restitution, impact duration) of the chunk
    columns.update(_closed_forms(config, ClosedFormCells(terms, reached, regular, pairs, posture_of_cell, r, t)))

    if config.friction:
        columns["friction"] = np.asarray(config.friction)[f]
        columns["tangential_speed"] = np.asarray(config.tangential_speed)[g]
        columns.update(_frictional_closed_forms(config, columns, q, regular[posture_of_cell]))

    # 4. --simulate
    if simulation is not None:
        columns.update(_simulate(config, simulation, cell, columns, q, regular[posture_of_cell]))
    return columns


def _frictional_closed_forms(config: SweepConfig, columns: dict, q: np.ndarray, regular: np.ndarray) -> dict[str, list]:
    """Per jump model m: ``friction_speed_m`` (m/s), ``friction_criterion_m``, ``friction_joint_m``,
    ``friction_block_m`` and ``friction_mode_m`` of ``frictional_max_speed`` in every regular cell
    (NaN, "" and 0 elsewhere)."""
    robot = _kinematics(config.choice).robot
    out = {f"friction_{what}_{m}": [] for m in config.jump_models for what in ("speed", "criterion", "joint", "block", "mode")}
    for i in range(q.shape[0]):
        normal = np.array([columns["normal_x"][i], columns["normal_y"][i], columns["normal_z"][i]])
        terms = robot.terms(q[i]) if regular[i] else None
        tangential = float(columns["tangential_speed"][i]) * tangential_direction(normal)
        rows = FrictionRows(float(columns["friction"][i]), config.pyramid_edges)
        for m in config.jump_models:
            answer = None
            if terms is not None:
                setting = Setting(m, float(columns["restitution"][i]), impact_duration=float(columns["impact_duration"][i]))
                answer = frictional_max_speed(robot, terms, normal, tangential, setting, rows)
            for what, value in (("speed", answer.max_speed.speed if answer else np.nan),
                                ("criterion", answer.max_speed.criterion if answer else ""),
                                ("joint", answer.max_speed.joint if answer else 0),
                                ("block", answer.block if answer else ""), ("mode", answer.mode if answer else "")):
                out[f"friction_{what}_{m}"].append(value)
    return out


def _simulate(config, simulation, cell, columns, q, regular) -> dict[str, list]:
    simulated, qp_limited, impacts, status = [], [], [], []
    for i in range(cell.size):
        point = np.array([columns["point_x"][i], columns["point_y"][i], columns["point_z"][i]])
        normal = np.array([columns["normal_x"][i], columns["normal_y"][i], columns["normal_z"][i]])
        result = (float("nan"), float("nan"), 0, "unreachable")
        if regular[i]:
            surface = Surface(point, normal, DEFAULT_WALL.friction)
            search = MaxSpeedSearch(
                ImpactPosture(f"cell{cell[i]}", q[i].copy(), "sweep cell", surface), surface, simulation.plant,
                setting=QpSetting(
                    columns["controller_jump_model"][i], float(columns["restitution"][i]),
                    float(columns["impact_duration"][i]),
                ),
                tolerance=config.tolerance, choice=config.choice,
            )
            try:
                report = search.run()
                result = (report.simulated_max_speed, report.qp_limited.contact_speed, len(report.evaluations),
                          "simulated")
            except UnreachableStartError:
                result = (float("nan"), float("nan"), 0, "no_start")
            except ImpactNotFoundError:
                result = (float("nan"), float("nan"), 0, "no_impact")
        for column, value in zip((simulated, qp_limited, impacts, status), result):
            column.append(value)
    return {
        "simulated_max_speed": simulated,
        "qp_limited_speed": qp_limited,
        "simulated_impacts": impacts,
        "simulated_status": status,
    }
