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
    significant_gain,
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


@given(st.lists(st.floats(0.5, 5.0), min_size=3, max_size=30), st.floats(0.05, 0.9), st.data())
def test_a_drop_in_every_trial_is_significant_and_a_rise_never_is(before, share, data):
    """Every trial's held-out residual lower by the same share: the differences of their
    squares all positive with a spread below their mean times sqrt(n) / t, or of one sign
    and equal (zero spread), so the paired test holds the drop, and never the rise back."""
    before = np.array(before)
    after = (1.0 - share) * before
    d = before**2 - after**2
    if d.mean() * np.sqrt(len(d)) >= 7.0 * d.std(ddof=1):  # t >= 7 beyond t_0.99 of 2 or more degrees of freedom
        assert significant_gain(before, after)
    assert not significant_gain(after, before)
    permutation = data.draw(st.permutations(range(len(before))))
    assert significant_gain(before[permutation], after[permutation]) == significant_gain(before, after)


def test_no_change_and_one_trial_are_never_significant():
    assert not significant_gain(np.ones(5), np.ones(5))
    assert not significant_gain(np.array([2.0]), np.array([1.0]))


def test_gains_of_both_signs_are_not_significant():
    """Half the trials better, half worse by the same amount: the mean difference is 0."""
    before = np.array([2.0, 2.0, 2.0, 2.0])
    after = np.sqrt(before**2 + np.array([-1.0, 1.0, -1.0, 1.0]))
    assert not significant_gain(before, after)
