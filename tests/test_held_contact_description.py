"""Held contacts and stances of a robot description (controller/model/held_contact_description.py)."""

import pytest

from impactqp.controller.model.held_contact_description import MAX_SURFACE_HEIGHT, Stance, stances_of
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.validation import BadInputError


def test_a_stance_without_heights_stands_on_the_floor_and_one_with_heights_on_its_surfaces():
    stances = stances_of({
        "flat": {"feet": [[0.0, 0.1], [0.0, -0.1]], "hand": [0.3, 0.0, 0.9]},
        "step": {"feet": [[0.0, 0.1], [0.0, -0.1]], "hand": [0.3, 0.0, 0.9], "heights": [0.12, 0.0]},
    }, 2, "robot")
    assert stances["flat"].coplanar and stances["flat"].height(1) == 0.0
    assert not stances["step"].coplanar and (stances["step"].height(0), stances["step"].height(1)) == (0.12, 0.0)
    assert Stance("s", ((0.0, 0.0),), (0.0, 0.0, 1.0), (0.0,)).coplanar


def test_the_g1_s_flat_stances_are_unchanged_and_its_step_stance_raises_the_left_foot():
    stances = ROBOTS["g1"].stances
    assert all(stances[name].coplanar for name in ("parallel", "wide", "staggered", "close", "far"))
    assert stances["step"].heights == (0.10, 0.0)


@pytest.mark.parametrize("heights, message", [
    ([0.1], "heights must be 2 numbers"),
    ([-0.01, 0.0], "heights"),
    ([MAX_SURFACE_HEIGHT + 0.1, 0.0], "heights"),
    (["high", 0.0], "heights"),
])
def test_bad_heights_are_one_line_of_bad_input(heights, message):
    table = {"s": {"feet": [[0.0, 0.1], [0.0, -0.1]], "hand": [0.3, 0.0, 0.9], "heights": heights}}
    with pytest.raises(BadInputError, match=message) as error:
        stances_of(table, 2, "robot")
    assert "\n" not in str(error.value)
