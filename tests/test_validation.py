"""The one validation module (controller/model/validation.py)."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.model.validation import (
    MAX_GAIN,
    BadInputError,
    all_finite,
    boolean,
    file_inside,
    finite_array,
    finite_vector,
    name_in,
    non_empty_list,
    non_empty_string,
    number,
    numbers,
    positive,
    positive_vector,
    table,
    tangential_velocity,
    task_gain,
    trial_count,
    unit_normal,
    unit_normals,
    vector_in_range,
)

any_floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(0, 40), elements=any_floats), arrays(np.float64, 7, elements=any_floats))
def test_all_finite_is_the_entrywise_test(a, b):
    """Short and long vectors alike, huge finite entries included."""
    assert all_finite(a, b) == bool(np.all(np.isfinite(a)) and np.all(np.isfinite(b)))
    assert all_finite(np.full(3, 1e300), np.full(40, 1e300))  # dot products would overflow


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-1e300, 1e300)).filter(lambda n: np.abs(n).max() > 1e-6))
def test_unit_normal_has_norm_one_and_keeps_the_direction(normal):
    n = unit_normal(normal)
    assert np.linalg.norm(n) == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(np.cross(n, normal / np.abs(normal).max()), 0.0, atol=1e-12)


@pytest.mark.parametrize("bad", [[np.nan, 0, 1], [np.inf, 0, 0], [0, 0, 0], [1, 2], "up"])
def test_bad_normals_are_bad_input(bad):
    with pytest.raises(BadInputError, match="the surface normal"):
        unit_normal(bad)
    if bad != [0, 0, 0]:
        with pytest.raises(BadInputError):
            finite_vector(bad, 3, "the surface normal")


@pytest.mark.filterwarnings("error")  # an overflow warning would print beside the one error line
@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, (4, 3), elements=st.floats(-1.7e308, 1.7e308)).filter(lambda n: np.all(np.abs(n).max(axis=1) > 1e-6)))
def test_unit_normals_are_the_rows_unit_normal_up_to_the_float_range(normals):
    np.testing.assert_allclose(unit_normals(normals), [unit_normal(n) for n in normals], rtol=0.0, atol=1e-15)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("velocity, given", [([0.0, 1e308, 0.0], "1e+308"), ([0.0, 1.7e308, 1.7e308], "1.7e+308"),
                                             ([0.0, 4.0, 0.0], "4")])
def test_a_too_fast_tangential_velocity_names_the_number_given(velocity, given):
    with pytest.raises(BadInputError, match=re.escape(f"at most 3.0 m/s, got {given} m/s")):
        tangential_velocity(velocity, np.array([-1.0, 0.0, 0.0]))


not_numbers = st.one_of(st.booleans(), st.text(max_size=3), st.none(), st.lists(st.integers(), max_size=2))


@given(st.one_of(st.integers(-(2**60), 2**60), st.floats(allow_nan=True, allow_infinity=True)))
def test_a_number_is_any_int_or_float_as_a_float(value):
    result = number(value, "x")
    assert isinstance(result, float) and (result == float(value) or np.isnan(value))


@given(not_numbers)
def test_a_boolean_a_string_or_a_list_is_not_a_number(value):
    with pytest.raises(BadInputError, match="x must be a number, got a"):
        number(value, "x")


@given(st.lists(st.floats(allow_nan=False), min_size=0, max_size=4), st.integers(0, 4))
def test_numbers_are_a_list_of_exactly_count_numbers(values, count):
    if len(values) == count:
        assert numbers(values, count, "p") == tuple(values)
    else:
        with pytest.raises(BadInputError, match=f"p must be a list of {count} numbers"):
            numbers(values, count, "p")
    if count:
        with pytest.raises(BadInputError, match=r"p\[0\] must be a number"):
            numbers([True] + [0.0] * (count - 1), count, "p")


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_positive_is_a_finite_number_above_zero(value):
    if np.isfinite(value) and value > 0.0:
        assert positive(value, "the spacing", "m") == value
    else:
        with pytest.raises(BadInputError, match="the spacing must be > 0 m, got"):
            positive(value, "the spacing", "m")


@given(arrays(np.float64, 3, elements=any_floats))
def test_positive_vector_needs_every_entry_finite_and_above_zero(value):
    if np.all(np.isfinite(value) & (value > 0.0)):
        np.testing.assert_array_equal(positive_vector(value, 3, "dq_max"), value)
    else:
        with pytest.raises(BadInputError, match="dq_max must be"):
            positive_vector(value, 3, "dq_max")


@given(arrays(np.float64, 3, elements=any_floats), st.floats(1e-3, 1e3))
def test_a_bounded_positive_vector_has_every_entry_in_zero_to_high(value, high):
    if np.all(np.isfinite(value) & (value > 0.0) & (value <= high)):
        np.testing.assert_array_equal(positive_vector(value, 3, "the stiffness", high), value)
    else:
        with pytest.raises(BadInputError, match=r"the stiffness must (lie in \(0, |be )"):
            positive_vector(value, 3, "the stiffness", high)


@pytest.mark.parametrize("bad", [[True, 0.0, 0.0], (0.0, np.bool_(False), 1.0), np.array([True, False, True]), True])
def test_a_boolean_is_never_an_entry_of_a_vector(bad):
    with pytest.raises(BadInputError, match="must be a vector of numbers"):
        finite_vector(bad, 3, "the point")


@given(arrays(np.float64, st.sampled_from([(3, 3), (3,), (2, 3)]), elements=any_floats))
def test_finite_array_needs_its_shape_and_finite_entries(value):
    if value.shape == (3, 3) and np.all(np.isfinite(value)):
        np.testing.assert_array_equal(finite_array(value, (3, 3), "R"), value)
    else:
        with pytest.raises(BadInputError, match=r"R must be \(3, 3\) finite values"):
            finite_array(value, (3, 3), "R")


@given(arrays(np.float64, 4, elements=st.floats(-20.0, 20.0)))
def test_vector_in_range_names_the_first_entry_outside(value):
    outside = np.flatnonzero((value < 0.0) | (value > 10.0))
    if outside.size == 0:
        np.testing.assert_array_equal(vector_in_range(value, 4, 0.0, 10.0, "armature", "kg m^2"), value)
    else:
        with pytest.raises(BadInputError, match=rf"armature\[{outside[0]}\] must lie in \[0, 10\] kg m\^2"):
            vector_in_range(value, 4, 0.0, 10.0, "armature", "kg m^2")


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_task_gain_lies_in_zero_to_max_gain(value):
    if 0.0 <= value <= MAX_GAIN:
        assert task_gain(value, "stiffness") == value
    else:
        with pytest.raises(BadInputError, match="stiffness must lie in"):
            task_gain(value, "stiffness")


@pytest.mark.parametrize("check, good, bad, message", [
    (non_empty_string, "elbow_up", ["", 5, None, ["a"]], "must be a non-empty string"),
    (non_empty_list, [0.0], [[], (0.0,), "a", None], "must be a non-empty list"),
    (table, {"a": 1}, [[("a", 1)], "a", None, 3], "must be a table of keys and values"),
])
def test_the_types_of_a_parsed_file(check, good, bad, message):
    assert check(good, "key") == good
    for value in bad:
        with pytest.raises(BadInputError, match=f"key {message}"):
            check(value, "key")


names = st.lists(st.text(st.characters(whitelist_categories=("Ll", "Nd")), min_size=1, max_size=5), min_size=1, max_size=3)


@given(names)
def test_a_relative_file_name_stays_inside_its_directory(parts):
    name = "/".join(parts)
    assert file_inside(name, "file", "the dataset directory") == name
    for escape in ("/" + name, "../" + name, name + "/../../x", "~/" + name):
        with pytest.raises(BadInputError, match="file must name a file inside the dataset directory"):
            file_inside(escape, "file", "the dataset directory")


@given(st.one_of(st.text(max_size=6), st.integers(), st.none()))
def test_name_in_accepts_only_one_of_the_choices(value):
    choices = ("crb", "gm", "classical")
    if value in choices:
        assert name_in(value, choices, "the model") == value
    else:
        with pytest.raises(BadInputError, match="the model = .*; choose from crb, gm, classical"):
            name_in(value, choices, "the model")


@given(st.one_of(st.booleans(), st.integers(0, 1), st.text(max_size=3), st.none()))
def test_boolean_accepts_only_true_and_false(value):
    if isinstance(value, bool):
        assert boolean(value, "flag") is value
    else:
        with pytest.raises(BadInputError, match="flag must be true or false"):
            boolean(value, "flag")



@given(st.integers(0, 10**6), st.integers(1, 10**6))
def test_a_trial_count_passes_exactly_up_to_its_limit(count, limit):
    if count <= limit:
        assert trial_count(count, limit, "the request") == count
    else:
        with pytest.raises(BadInputError, match=f"the request has {count:,} trials, more than the limit of {limit:,}"):
            trial_count(count, limit, "the request")


@pytest.mark.parametrize("limit", [0, -3, 2.5, True, None])
def test_a_trial_limit_is_a_whole_number_from_one(limit):
    with pytest.raises(BadInputError, match="--max-trials"):
        trial_count(1, limit, "the request")
