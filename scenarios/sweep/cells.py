"""Evaluation of sweep cells: contact posture by inverse kinematics, conditioning, closed form.

A cell is (point, normal, restitution). Its row holds the reachability of the contact posture
(:func:`controller.model.inverse_kinematics.contact_posture` from the config's seed), cond(M),
the contact Jacobian's singular-value ratio sigma_min / sigma_max and, for every jump model, the
closed-form highest feasible speed and what binds it (``closed_form_max_speed``). An unreachable
or singular cell keeps its row, with NaN speeds, an empty criterion and joint 0.
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.inverse_kinematics import contact_posture
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.max_speed import closed_form_max_speed
from impactqp.controller.model.robot import NQ, PandaModel, SingularPostureError

from .config import SweepConfig

_ROBOT: PandaModel | None = None


def _robot() -> PandaModel:
    """One Pinocchio model per process (workers build theirs once)."""
    global _ROBOT
    if _ROBOT is None:
        _ROBOT = PandaModel()
    return _ROBOT


def cell_settings(config: SweepConfig, cell: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(point, normal, restitution) of cell index ``cell``; restitution varies fastest."""
    n_r, n_n = len(config.restitution), len(config.normals)
    r = cell % n_r
    k = (cell // n_r) % n_n
    p = cell // (n_r * n_n)
    return config.points()[p], np.asarray(config.normals[k]), config.restitution[r]


def evaluate_cells(config: SweepConfig, cells: range) -> list[dict]:
    """The rows of ``cells`` (a contiguous range of cell indices), in order."""
    robot = _robot()
    points = config.points()
    n_r, n_n = len(config.restitution), len(config.normals)
    rows = []
    posture_cache: dict[tuple[int, int], tuple] = {}
    for cell in cells:
        p, k, r = cell // (n_r * n_n), (cell // n_r) % n_n, cell % n_r
        point, normal, c_r = points[p], np.asarray(config.normals[k]), config.restitution[r]
        if (p, k) not in posture_cache:
            solved = contact_posture(robot, point, normal, config.seed)
            terms = None
            if solved.reachable:
                try:
                    terms = robot.terms(solved.q)
                except SingularPostureError:
                    terms = None
            posture_cache[(p, k)] = (solved, terms)
        solved, terms = posture_cache[(p, k)]
        row = {
            "cell": cell,
            "point_x": float(point[0]),
            "point_y": float(point[1]),
            "point_z": float(point[2]),
            "normal_x": float(normal[0]),
            "normal_y": float(normal[1]),
            "normal_z": float(normal[2]),
            "restitution": float(c_r),
            "reachable": bool(solved.reachable),
            "singular": bool(solved.reachable and terms is None),
            "position_error": solved.position_error,
            "axis_error": solved.axis_error,
        }
        for j in range(NQ):
            row[f"q{j + 1}"] = float(solved.q[j])
        if terms is not None:
            s = np.linalg.svd(terms.J, compute_uv=False)
            row["cond_M"] = terms.cond_M
            row["jacobian_sv_ratio"] = float(s[-1] / s[0])
        else:
            row["cond_M"] = row["jacobian_sv_ratio"] = float("nan")
        for name in config.jump_models:
            if terms is not None:
                best = closed_form_max_speed(
                    robot, terms, normal, jump_model(name), c_r, config.impact_duration
                )
                speed, criterion, joint = best.speed, best.criterion, best.joint
            else:
                speed, criterion, joint = float("nan"), "", 0
            row[f"speed_{name}"] = float(speed)
            row[f"criterion_{name}"] = criterion
            row[f"joint_{name}"] = int(joint)
        rows.append(row)
    return rows
