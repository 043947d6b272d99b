import tomllib

import numpy as np

from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.max_speed import closed_form_max_speed
from impactqp.scenarios.sweep.cells import cell_settings, evaluate_cells
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config


def config_with(**grid):
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(grid)
    data["settings"]["restitution"] = [0.0, 0.5]
    return parse_config(data)


def test_a_cell_speed_equals_the_closed_form_of_max_speed_at_the_same_posture(robot):
    config = config_with(size=[0.2, 0.2], spacing=0.1)
    rows = evaluate_cells(config, range(config.cell_count()))
    reachable = [r for r in rows if r["reachable"] and not r["singular"]]
    assert reachable
    for row in reachable:
        point, normal, c_r = cell_settings(config, row["cell"])
        q = np.array([row[f"q{j}"] for j in range(1, 8)])
        assert np.allclose(robot.contact_point(q), point, atol=1e-5)
        terms = robot.terms(q)
        for name in config.jump_models:
            best = closed_form_max_speed(robot, terms, normal, jump_model(name), c_r, config.impact_duration)
            assert row[f"speed_{name}"] == best.speed
            assert row[f"criterion_{name}"] == best.criterion and row[f"joint_{name}"] == best.joint


def test_unreachable_cells_keep_their_row_with_no_speed():
    config = config_with(origin=[1.5, 0.0, 0.5], size=[0.1, 0.0], spacing=0.1)
    rows = evaluate_cells(config, range(config.cell_count()))
    assert [r["cell"] for r in rows] == list(range(config.cell_count()))
    for row in rows:
        assert not row["reachable"]
        assert all(np.isnan(row[f"speed_{m}"]) and row[f"joint_{m}"] == 0 for m in config.jump_models)
