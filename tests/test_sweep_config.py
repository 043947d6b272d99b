import tomllib

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
    ],
)
def test_bad_configs_are_refused_with_a_message_naming_the_key(edit, message):
    data = example()
    edit(data)
    with pytest.raises(BadInputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_config(data)


def test_a_malformed_file_is_bad_input(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[grid\n")
    with pytest.raises(BadInputError, match="malformed"):
        load_config(path)
