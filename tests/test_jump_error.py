"""The error metrics of eqs. (25) and (26): identities that hold for any pair of jumps."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from impactqp.controller.model.jump_error import average_prediction_error, prediction_error

values = st.floats(-10.0, 10.0, allow_nan=False)
jumps = st.integers(1, 12).flatmap(lambda n: st.tuples(*(arrays(float, n, elements=values) for _ in range(3))))


@given(jumps)
def test_the_error_is_the_difference_and_the_average_its_mean_magnitude(triple):
    predicted, measured, _ = triple
    np.testing.assert_array_equal(prediction_error(predicted, measured), predicted - measured)
    assert average_prediction_error(predicted, measured) == np.abs(predicted - measured).sum() / predicted.size


@given(jumps, st.floats(0.0, 5.0))
def test_the_average_error_is_a_scaled_distance(triple, scale):
    a, b, c = triple
    d = average_prediction_error
    assert d(a, a) == 0.0
    assert d(a, b) >= 0.0 and d(a, b) == d(b, a)
    assert d(a, c) <= d(a, b) + d(b, c) + 1e-12
    np.testing.assert_allclose(d(scale * a, scale * b), scale * d(a, b), rtol=1e-12, atol=1e-12)


@given(jumps)
def test_a_batch_of_trials_is_one_call_over_the_last_axis(triple):
    a, b, c = triple
    batch = average_prediction_error(np.stack([a, b]), c)
    np.testing.assert_array_equal(batch, [average_prediction_error(a, c), average_prediction_error(b, c)])
