import tomllib

import time

import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.sweep.config import EXAMPLE, load_config, parse_config


def example() -> dict:
    return tomllib.loads(EXAMPLE)


def test_the_example_config_is_valid_and_its_grid_has_the_product_of_its_axes():
    config = parse_config(example())
    nu = round(config.size[0] / config.spacing) + 1
    nv = round(config.size[1] / config.spacing) + 1
    assert len(config.points()) == nu * nv
    assert config.cell_count() == nu * nv * len(config.normals) * len(config.restitution)


def test_every_list_of_settings_and_of_controller_settings_is_an_axis_of_the_grid():
    data = example()
    data["settings"].update(normals=[[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]], restitution=[0.0, 0.2, 0.4])
    data["controller"].update(jump_model=["crb", "gm"], impact_duration=[0.01, 0.02])
    config = parse_config(data)
    points = len(config.points())
    assert config.cell_count() == points * 2 * 3 * 2 * 2
    keys = set(zip(*(axis.tolist() for axis in config.cell_axes(range(config.cell_count())))))
    assert len(keys) == config.cell_count()  # every cell a distinct combination


def test_every_line_of_the_example_that_sets_a_key_follows_a_comment():
    lines = EXAMPLE.splitlines()
    for i, line in enumerate(lines):
        if "=" in line and not line.startswith("#"):
            j = i - 1
            while j >= 0 and lines[j] and not lines[j].startswith(("#", "[")) and "=" in lines[j]:
                j -= 1  # keys sharing one comment (u and v)
            assert lines[j].startswith("#"), line


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d["grid"].update(foo=1), "unknown key grid.foo"),
        (lambda d: d.update(extra={}), "unknown key extra"),
        (lambda d: d["grid"].update(spacing=0.0), "grid.spacing must be > 0"),
        (lambda d: d["grid"].update(spacing=-0.1), "grid.spacing must be > 0"),
        (lambda d: d["settings"].update(normals=[]), "empty"),
        (lambda d: d["settings"].update(restitution=[]), "empty"),
        (lambda d: d["settings"].update(restitution=[1.5]), "settings.restitution[0]"),
        (lambda d: d["settings"].update(normals=[[0.0, 0.0, 0.0]]), "settings.normals[0]"),
        (lambda d: d["settings"].update(jump_models=["nope"]), "unknown jump model"),
        (lambda d: d["settings"].pop("seed_posture"), "missing key settings.seed_posture"),
        (lambda d: d["controller"].update(gain=1.0), "unknown key controller.gain"),
        (lambda d: d["controller"].update(jump_model=[]), "empty"),
        (lambda d: d["controller"].update(jump_model=["nope"]), "controller.jump_model"),
        (lambda d: d["controller"].update(impact_duration=[0.0]), "controller.impact_duration[0]"),
        (lambda d: d["controller"].update(impact_duration=[0.01, 0.01]), "twice"),
        (lambda d: d["simulate"].update(tolerance=0.0), "simulate.tolerance must be > 0"),
        (lambda d: d.pop("simulate"), r"needs a [simulate] table"),
        (lambda d: d["grid"].update(size=[10.0, 10.0], spacing=0.001), "more than 10,000,000"),
        (lambda d: d["grid"].update(size=[1e300, 0.1], spacing=1e-300), "more than 10,000,000"),
        (lambda d: d["grid"].update(u=[1.0, 0.0, 0.0], v=[-2.0, 0.0, 0.0]), "parallel"),
    ],
)
def test_bad_configs_are_refused_with_a_message_naming_the_key(edit, message):
    data = example()
    edit(data)
    start = time.perf_counter()
    with pytest.raises(BadInputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_config(data)
    assert time.perf_counter() - start < 5.0


def test_a_malformed_file_is_bad_input(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[grid\n")
    with pytest.raises(BadInputError, match="the sweep config .* is not valid TOML"):
        load_config(path)
