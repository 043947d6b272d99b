import tomllib

import numpy as np
import pytest

from impactqp.controller.model.max_speed import Setting, closed_form_max_speed, criterion_slopes
from impactqp.scenarios.max_speed_search import predicted_max_speeds
from impactqp.scenarios.sweep.cells import Simulation, cell_settings, evaluate_cells
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config


def config_with(**grid):
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(grid)
    data["settings"].update(restitution=[0.0, 0.5], jump_models=["classical", "gm", "crb"])
    data["controller"].update(impact_duration=[0.015, 0.03], jump_model=["crb", "robust"])
    return parse_config(data)


def test_a_cell_speed_equals_the_closed_form_of_max_speed_at_the_same_posture(robot):
    config = config_with(size=[0.2, 0.2], spacing=0.1)
    columns = evaluate_cells(config, range(config.cell_count()))
    rows = [dict(zip(columns, values)) for values in zip(*columns.values())]
    assert [r["cell"] for r in rows] == list(range(config.cell_count()))
    reachable = [r for r in rows if r["reachable"] and not r["singular"]]
    assert reachable and len(reachable) < len(rows)
    for row in reachable:
        cell = cell_settings(config, row["cell"])
        assert row["restitution"] == cell["restitution"] and row["impact_duration"] == cell["impact_duration"]
        assert row["controller_jump_model"] == cell["controller_jump_model"]
        q = np.array([row[f"q{j}"] for j in range(1, 8)])
        assert np.linalg.norm(robot.contact_point(q) - cell["point"]) <= 1e-6
        assert robot.contact_frame(q).rotation[:, 2] @ -cell["normal"] > 1.0 - 1e-9
        predicted = predicted_max_speeds(robot, q, cell["normal"], cell["restitution"], cell["impact_duration"])
        terms = robot.terms(q)
        assert row["cond_M"] == pytest.approx(np.linalg.cond(terms.M), rel=1e-9)
        s = np.linalg.svd(terms.J, compute_uv=False)
        assert row["jacobian_sv_ratio"] == pytest.approx(s[-1] / s[0], rel=1e-9)
        for name in config.jump_models:
            best = predicted[name]
            setting = Setting(name, cell["restitution"], impact_duration=cell["impact_duration"])
            assert best == closed_form_max_speed(robot, terms, cell["normal"], setting)
            assert row[f"speed_{name}"] == pytest.approx(best.speed, rel=1e-9)
            # what binds is max-speed's, or binds at the same speed (a tie to rounding)
            slopes = criterion_slopes(robot, terms, cell["normal"], setting)
            binding = slopes[row[f"criterion_{name}"]][row[f"joint_{name}"] - 1]
            assert 1.0 / binding == pytest.approx(best.speed, rel=1e-9)


def test_a_chunk_gives_the_rows_of_the_whole_grid_for_its_cells():
    config = config_with(size=[0.1, 0.1], spacing=0.1)
    whole = evaluate_cells(config, range(config.cell_count()))
    part = evaluate_cells(config, range(5, 21))
    for name, values in part.items():
        assert repr(list(values)) == repr(list(whole[name][5:21])), name


def test_unreachable_cells_keep_their_row_with_no_speed_and_are_not_simulated():
    config = config_with(origin=[1.5, 0.0, 0.5], size=[0.1, 0.0], spacing=0.1)
    columns = evaluate_cells(config, range(config.cell_count()), Simulation())
    assert list(columns["cell"]) == list(range(config.cell_count()))
    assert not np.any(columns["reachable"])
    for m in config.jump_models:
        assert np.all(np.isnan(columns[f"speed_{m}"])) and not np.any(columns[f"joint_{m}"])
    assert set(columns["simulated_status"]) == {"unreachable"}
    assert np.all(np.isnan(columns["simulated_max_speed"])) and np.all(np.isnan(columns["qp_limited_speed"]))


def test_the_controller_jump_model_feeds_the_qp_limited_run_and_not_the_bisection():
    """One point (the tip of elbow_up), the controller's constraints with crb and with gm (whose
    closed-form speeds differ by more than 2x there): the QP-limited speeds differ, the simulated
    highest speed (jump-aware constraints off) is the same."""
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(origin=[0.6, 0.0, 0.7], size=[0.0, 0.0])
    data["controller"].update(jump_model=["crb", "gm"])
    data["simulate"].update(tolerance=0.1)
    config = parse_config(data)
    columns = evaluate_cells(config, range(config.cell_count()), Simulation())
    assert columns["controller_jump_model"] == ["crb", "gm"]
    assert columns["simulated_status"] == ["simulated", "simulated"]
    assert columns["simulated_max_speed"][0] == columns["simulated_max_speed"][1]
    crb, gm = columns["qp_limited_speed"]
    assert crb < gm


def test_a_friction_cell_is_the_closed_form_under_the_robust_rows_and_friction_only_adds_rows(robot):
    """With [friction]: each cell's friction columns are ``frictional_max_speed`` at its posture,
    mu and sliding speed along t = normalise(n x e_z); at mu = 0 and v_t = 0 they are the
    frictionless closed form of the same cell; at any mu, no faster than mu = 0 at the same v_t."""
    from impactqp.controller.model.friction_pyramid import FrictionRows
    from impactqp.controller.model.friction_max_speed import frictional_max_speed

    data = tomllib.loads(EXAMPLE)
    data["grid"].update(origin=[0.6, 0.0, 0.7], size=[0.0, 0.0])
    data["settings"].update(jump_models=["classical", "crb"])
    data["friction"] = {"mu": [0.0, 0.2, 0.5], "tangential_speed": [0.0, 0.08], "pyramid_edges": 5}
    config = parse_config(data)
    columns = evaluate_cells(config, range(config.cell_count()))
    rows = [dict(zip(columns, values)) for values in zip(*columns.values())]
    assert len(rows) == 6 and all(r["reachable"] and not r["singular"] for r in rows)
    by_key = {(r["friction"], r["tangential_speed"]): r for r in rows}
    for row in rows:
        cell = cell_settings(config, row["cell"])
        assert (row["friction"], row["tangential_speed"]) == (cell["friction"], cell["tangential_speed"])
        q = np.array([row[f"q{j}"] for j in range(1, 8)])
        tangent = np.cross(cell["normal"], [0.0, 0.0, 1.0])
        tangential = cell["tangential_speed"] * tangent / np.linalg.norm(tangent)
        for name in config.jump_models:
            answer = frictional_max_speed(robot, robot.terms(q), cell["normal"], tangential,
                                          Setting(name, cell["restitution"], impact_duration=cell["impact_duration"]),
                                          FrictionRows(cell["friction"], 5))
            assert row[f"friction_speed_{name}"] == pytest.approx(answer.max_speed.speed, rel=1e-12)
            assert (row[f"friction_block_{name}"], row[f"friction_mode_{name}"]) == (answer.block, answer.mode)
            assert row[f"friction_speed_{name}"] <= by_key[(0.0, row["tangential_speed"])][f"friction_speed_{name}"] * (1 + 1e-12)
            if row["friction"] == 0.0 and row["tangential_speed"] == 0.0:
                assert row[f"friction_speed_{name}"] == pytest.approx(row[f"speed_{name}"], rel=1e-9)
