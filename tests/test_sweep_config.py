import tomllib

import time

import numpy as np

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
        (lambda d: d["simulate"].update(tolerance=0.0), "simulate.tolerance must lie in [0.0001, 0.5] m/s, got 0.0"),
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


def friction_example(**table) -> dict:
    data = example()
    data["friction"] = {"mu": [0.1, 0.3], "tangential_speed": [0.0, 0.05, 0.1], "pyramid_edges": 4} | table
    return data


def test_the_friction_table_adds_two_axes_and_leaves_a_sweep_without_it_as_it_was():
    plain = parse_config(example())
    config = parse_config(friction_example())
    assert config.cell_count() == plain.cell_count() * 2 * 3
    keys = set(zip(*(axis.tolist() for axis in config.cell_axes(range(config.cell_count())))))
    assert len(keys) == config.cell_count()
    assert (config.friction, config.tangential_speed, config.pyramid_edges) == ((0.1, 0.3), (0.0, 0.05, 0.1), 4)
    # without [friction]: the same cells in the same order, the same identity
    assert plain.axes_shape()[-2:] == (1, 1)
    assert [a.tolist() for a in plain.cell_axes(range(plain.cell_count()))][:5] == [
        a.ravel().tolist() for a in np.indices(plain.axes_shape()[:5]).reshape(5, -1)]
    assert "friction" not in plain.canonical_json() and "tangential_speed" not in plain.canonical_json()
    assert config.canonical_json() != parse_config(friction_example(mu=[0.1, 0.4])).canonical_json()


@pytest.mark.parametrize(
    "table, message",
    [
        ({"mu": [2.5]}, "friction.mu[0]"),
        ({"mu": [-0.1]}, "friction.mu[0]"),
        ({"mu": []}, "friction.mu must be a non-empty list"),
        ({"mu": [0.1, 0.1]}, "friction.mu lists a value twice"),
        ({"pyramid_edges": 2}, "friction.pyramid_edges"),
        ({"tangential_speed": [-0.01]}, "friction.tangential_speed[0]"),
        ({"tangential_speed": [3.0]}, "friction.tangential_speed[0]"),
        ({"tangential_speed": [0.1, 0.1]}, "friction.tangential_speed lists a value twice"),
        ({"angle": 1.0}, "unknown key friction.angle"),
    ],
)
def test_bad_friction_tables_are_refused_naming_the_key(table, message):
    with pytest.raises(BadInputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_config(friction_example(**table))


def test_a_friction_sweep_refuses_the_normal_only_classical_model_and_a_missing_key():
    data = friction_example()
    data["settings"]["jump_models"] = ["classical_normal", "crb"]
    with pytest.raises(BadInputError, match="classical_normal"):
        parse_config(data)
    data = friction_example()
    del data["friction"]["pyramid_edges"]
    with pytest.raises(BadInputError, match="missing key friction.pyramid_edges"):
        parse_config(data)


@pytest.mark.parametrize("table, key, values, message", [
    ("settings", "restitution", [0.0, 0.3, 0.0], "settings.restitution[0] and settings.restitution[2] are equal"),
    ("settings", "restitution", [0.0, -0.0], "settings.restitution[0] and settings.restitution[1] are equal"),
    ("settings", "normals", [[-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]], "settings.normals[0] and settings.normals[1] are one"),
    ("settings", "normals", [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [-2.0, 0.0, 0.0]],
     "settings.normals[0] and settings.normals[2] are one direction (normals are normalised)"),
    ("settings", "normals", [[-1.0, 0.1, 0.0], [-3.0, 0.3, 0.0]], "settings.normals[0] and settings.normals[1] are one"),
    ("settings", "jump_models", ["gm", "crb", "gm"], "settings.jump_models[0] and settings.jump_models[2] are equal"),
    ("controller", "jump_model", ["crb", "crb"], "controller.jump_model[0] and controller.jump_model[1] are equal"),
])
def test_a_value_listed_twice_is_refused_naming_the_key_and_its_entries(table, key, values, message):
    """Every list of the config is an axis or a set of models: a repeat would duplicate cells or
    columns. Normals compare as directions (normalised: -2 e_x is -e_x, and 3 (-1, 0.1, 0) is
    (-1, 0.1, 0) up to rounding); 0.0 and -0.0 are one restitution."""
    data = example()
    data[table][key] = values
    with pytest.raises(BadInputError) as refused:
        parse_config(data)
    assert str(refused.value).startswith(f"{table}.{key} lists a value twice: ")
    assert message in str(refused.value)


def test_distinct_normals_close_to_one_another_are_two_axes_values():
    """Directions 1e-6 rad apart are not a repeat: only rounding-level differences are."""
    data = example()
    data["settings"]["normals"] = [[-1.0, 0.0, 0.0], [-1.0, 1e-6, 0.0]]
    assert len(parse_config(data).normals) == 2


@pytest.mark.parametrize("tolerance", [0.0, 0.99e-4, 0.51, -0.005, True, "0.005"])
def test_a_tolerance_outside_the_range_of_max_speed_is_refused_naming_the_key(tolerance):
    """The bisection tolerance of docs/errors.md, 0.1 mm/s to 0.5 m/s: what ``max-speed
    --tolerance`` accepts, whether or not the sweep simulates."""
    data = example()
    data["simulate"]["tolerance"] = tolerance
    with pytest.raises(BadInputError, match=r"^simulate\.tolerance must (lie|be a number) in \[0\.0001, 0\.5\] m/s"):
        parse_config(data)


@pytest.mark.parametrize("tolerance", [1e-4, 0.5])
def test_the_ends_of_the_tolerance_range_are_accepted(tolerance):
    data = example()
    data["simulate"]["tolerance"] = tolerance
    assert parse_config(data).tolerance == tolerance
