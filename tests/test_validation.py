"""The one validation module (controller/model/validation.py)."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.model.validation import (
    BadInputError,
    all_finite,
    finite_vector,
    tangential_velocity,
    unit_normal,
    unit_normals,
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
