"""Cross-validation of the causes on held-out error (sim/diagnosis/selection.py)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from impactqp.sim.causes import FrictionCause
from impactqp.sim.diagnosis.selection import (
    MAX_FOLDS,
    STEP_GAIN,
    fold_of,
    relative_gain,
    selection_step,
)


@given(st.integers(1, 40))
def test_folds_split_the_trials_evenly_into_at_most_max_folds(count):
    folds = fold_of([None] * count)
    sizes = np.bincount(folds)
    assert len(sizes) == min(MAX_FOLDS, count) and sizes.max() - sizes.min() <= 1


@given(st.floats(0.0, 10.0), st.floats(1e-6, 10.0))
def test_a_step_is_selected_when_it_removes_step_gain_of_the_error_before_it(error, previous):
    step = selection_step(FrictionCause(), error, previous)
    assert step["gain"] == pytest.approx(1.0 - error / previous)
    assert step["selected"] == (relative_gain(error, previous) >= STEP_GAIN)
    assert step["cause"] == "friction" and step["heldout_error"] == error


def test_without_a_reference_error_there_is_no_gain():
    assert relative_gain(0.5, 0.0) == 0.0
