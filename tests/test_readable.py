"""Numbers as a person reads them (scenarios/readable.py)."""

import re

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.scenarios.readable import boolean, fixed, number, parameters_text
from impactqp.sim.causes import ArmatureCause, JointDampingCause, PayloadCause

coordinates = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)


@given(st.lists(coordinates, min_size=1, max_size=7))
def test_fixed_writes_every_value_with_four_decimals_and_no_exponent(values):
    text = fixed(values)
    cells = text.strip("[]").split(", ")
    assert len(cells) == len(values)
    for cell, value in zip(cells, values):
        assert re.fullmatch(r"-?\d+\.\d{4}", cell), cell
        assert cell != "-0.0000"
        assert abs(float(cell) - value) <= 0.5e-4 + 1e-12


def test_a_contact_point_off_by_a_rounding_error_reads_as_zero():
    assert fixed([0.6, 7.9491e-08, -3e-9]) == "[0.6000, 0.0000, 0.0000]"


@given(st.floats(min_value=1e-4, max_value=9.99e5) | st.floats(min_value=-9.99e5, max_value=-1e-4))
def test_number_keeps_four_significant_digits_without_exponent_in_the_everyday_range(x):
    text = number(x)
    assert "e" not in text
    assert abs(float(text) - x) <= 5e-4 * abs(x)


def test_number_of_zero_is_zero():
    assert number(-0.0) == "0"


def test_booleans_are_written_as_json_writes_them():
    assert (boolean(True), boolean(False), boolean(np.bool_(True))) == ("true", "false", "true")


@given(st.floats(min_value=0.01, max_value=4.0), st.floats(min_value=0.01, max_value=4.0))
def test_per_joint_parameters_are_grouped_as_the_diagnosis_fits_them(a, b):
    """A cause fitted per joint group (1-4, 5-7) reads as one value per group, with its unit."""
    for cause, key in ((ArmatureCause(JOINTS), "armature"), (JointDampingCause(JOINTS), "joint_damping")):
        text = parameters_text(cause.overrides(np.array([a, b])))
        assert text.startswith(f"{key} (")
        assert f"joints 1-4 = {number(a)}, joints 5-7 = {number(b)}" in text
        assert "[" not in text


def test_vectors_that_are_not_per_group_are_listed():
    text = parameters_text(PayloadCause().overrides(np.array([0.5, 0.01, 0.0, -0.02])))
    assert text == "payload_mass (kg): 0.5; payload_com (m): [0.01, 0, -0.02]"
    ungrouped = [0.1, 0.2, 0.1, 0.1, 0.3, 0.3, 0.3]
    assert parameters_text({"armature": ungrouped}) == "armature (kg m^2): [0.1, 0.2, 0.1, 0.1, 0.3, 0.3, 0.3]"
    assert parameters_text({}) == "nominal"
