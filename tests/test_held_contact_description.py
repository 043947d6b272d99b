"""Held contacts and stances of a robot description (controller/model/held_contact_description.py)."""

import pytest

from impactqp.controller.model.held_contact_description import (
    MAX_SURFACE_HEIGHT,
    MIN_SOLE_AREA,
    Stance,
    convex_hull,
    held_contacts_of,
    polygon_area,
    stances_of,
)
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


SOLE = [[-0.05, 0.025], [-0.05, -0.025], [0.12, 0.03], [0.12, -0.03]]


def held_contact(sole):
    return [{"name": "foot", "frame": "ankle", "sole": sole, "depth": 0.03, "friction": 1.0}]


@pytest.mark.parametrize("sole, message", [
    ([[0.0, 0.0], [0.1], [0.0, 0.1]], "sole must be 3 or more"),
    ([[0.0, 0.0], ["a", "b"], [0.0, 0.1]], "sole must be 3 or more"),
    ([[True, False], [0.0, 0.1], [0.1, 0.0]], "sole must be 3 or more"),
    ([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], "enclose no area"),
    ([[0.0, 0.0], [0.05, 0.05], [0.1, 0.1]], "enclose no area"),
    ([[0.0, 0.0], [1e-300, 0.0], [0.0, 1e-300]], "enclose no area"),
])
def test_a_sole_that_is_no_polygon_is_one_line_of_bad_input(sole, message):
    """Ragged or non-numeric corners, booleans, and corners whose convex hull covers less than
    MIN_SOLE_AREA (coincident, collinear, tiny): refused when the description is read (the
    support polygon's edge normals divide by the edges' lengths)."""
    with pytest.raises(BadInputError, match=message) as error:
        held_contacts_of(held_contact(sole), "robot")
    assert "\n" not in str(error.value)


def test_a_sole_s_area_is_its_convex_hull_s_in_any_corner_order():
    """The shoelace area of the hull: the built-in sole's corners (given crossed, not around the
    polygon) enclose 0.17 x 0.05 plus the two triangles of the wider toe."""
    (contact,) = held_contacts_of(held_contact(SOLE), "robot")
    expected = 0.17 * 0.05 + 2 * 0.5 * 0.17 * 0.005
    assert polygon_area(convex_hull(contact.sole)) == pytest.approx(expected, rel=1e-12)
    assert polygon_area(convex_hull(contact.sole[::-1])) == pytest.approx(expected, rel=1e-12)
    assert expected > MIN_SOLE_AREA
