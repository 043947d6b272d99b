"""The replay's start spread (sim/diagnosis/start_spread.py): the std of every residual that the
replay's own noisy start velocity makes, and the fit test that counts it."""

from dataclasses import replace

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.sim.diagnosis.fitting import fit_report, residual_blocks
from impactqp.sim.diagnosis.start_spread import START_SAMPLES, start_spread
from impactqp.sim.diagnosis.trials import load_trials, locate_jump_samples, replay_all
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

FRICTION = 0.4186  # the wall's true mu: the tool's slip at 0.6 m/s ends inside the impact


@pytest.fixture(scope="module")
def sliding(tmp_path_factory):
    """A dataset of a wall with mu = FRICTION hit at two postures and two normal speeds, with and
    without tangential speeds (0.3 and 0.6 m/s: the tool slides), its trials located at the
    nominal plant, and the true plant."""
    directory = tmp_path_factory.mktemp("sliding") / "data"
    truth = PlantParameters(friction=FRICTION).for_joints(JOINTS)
    request = DatasetRequest(plant=truth, postures=["elbow_up", "elbow_left"], speeds=[0.1, 0.18],
                             tangential=[0.3, 0.6], seed=4005)
    generate_dataset(directory, request, jobs=1)
    trials, _, setting = load_trials(directory)
    return locate_jump_samples(trials, setting, PlantParameters().for_joints(JOINTS)), setting, truth


def test_noise_free_starts_have_no_spread_and_leave_the_residuals_as_they_were(sliding):
    """A trial whose dq shows no scatter starts where the robot was: no spread, and the
    residuals with that spread are the plain ones."""
    trials, setting, truth = sliding
    quiet = [replace(t, scatter=(np.zeros(JOINTS), t.scatter[1])) for t in trials[:2]]
    spreads = start_spread(setting, truth, quiet)
    assert all(not s for s in spreads)
    for f, t, s in zip(replay_all(setting, truth, quiet), quiet, spreads):
        plain, spread = residual_blocks(f, t), residual_blocks(f, t, s)
        assert plain.keys() == spread.keys()
        for name in plain:
            np.testing.assert_array_equal(plain[name], spread[name])


def test_a_residual_is_divided_by_its_spread_where_it_exceeds_the_noise(sliding):
    """With a spread s_i, residual i reads r_i / max(1, s_i): unchanged below one noise unit."""
    trials, setting, truth = sliding
    trial = trials[0]
    features = replay_all(setting, truth, [trial])[0]
    plain = residual_blocks(features, trial)
    rng = np.random.default_rng(3)
    spread = {name: rng.uniform(0.0, 3.0, value.shape) for name, value in plain.items()}
    scaled = residual_blocks(features, trial, spread)
    for name in plain:
        np.testing.assert_allclose(scaled[name] * np.maximum(spread[name], 1.0), plain[name], rtol=1e-12)


def test_the_spread_is_first_order_in_the_start_error(sliding):
    """Where the replay is smooth in its start (the torque before the contact), the spread is the
    first-order std of the start error: a start error twice as large (the scatter times 4)
    doubles it, half as large halves it. (What the contact follows is only piecewise smooth: the
    replay touches the wall at one of its physics steps, so the jump's spread is a secant.)"""
    trials, setting, truth = sliding
    normal = [t for t in trials if t.tangential_speed == 0.0][:2]
    once = start_spread(setting, truth, normal)
    for factor in (0.25, 4.0):
        scaled = [replace(t, scatter=(factor * t.scatter[0], t.scatter[1])) for t in normal]
        for spread, base in zip(start_spread(setting, truth, scaled), once):
            np.testing.assert_allclose(spread["torque"], np.sqrt(factor) * base["torque"], rtol=1e-2, atol=1e-9)


def test_the_spread_is_the_residuals_std_over_start_velocities_drawn_from_their_noise(sliding):
    """The replay started from velocities drawn about the logged start with the start mean's own
    std (sigma_j / sqrt(START_SAMPLES)): the residuals' spread over 40 draws (root mean square
    over a block) is the first-order spread's: the torque's within the draws' own scatter (a
    40-draw std is known to about 11 %; 35 % is three of those), the jump's within a factor 2
    (the contact's physics step makes it a secant, the module docstring)."""
    trials, setting, truth = sliding
    trial = [t for t in trials if t.tangential_speed == 0.0][0]
    spread = start_spread(setting, truth, [trial])[0]
    std = np.sqrt(trial.scatter[0] / START_SAMPLES)
    rng = np.random.default_rng(11)
    drawn = [replace(trial, dq0=trial.dq0 + rng.normal(0.0, std)) for _ in range(40)]
    blocks = [residual_blocks(f, t) for f, t in zip(replay_all(setting, truth, drawn), drawn)]
    ratio = {}
    for name in ("jump", "torque"):
        values = np.array([b[name] for b in blocks])
        ratio[name] = np.sqrt(np.mean(np.var(values, axis=0, ddof=1))) / np.sqrt(np.mean(spread[name] ** 2))
    assert 0.65 <= ratio["torque"] <= 1.35
    assert 0.5 <= ratio["jump"] <= 2.0


def test_the_true_plant_of_a_slip_that_ends_inside_the_impact_fits_with_its_start_spread(sliding):
    """The true plant replayed against its own noisy data: a trial at 0.6 m/s tangential, whose
    slip ends inside the impact, moves its joint jumps by many noise units with the start
    velocity's own error. Without the spread the true plant does not fit the noise (its jump
    block or a jump channel beyond the limits); with it, it does, and every other block is
    unchanged or lower."""
    trials, setting, truth = sliding
    features = replay_all(setting, truth, trials)
    spreads = start_spread(setting, truth, trials)
    plain, counted = fit_report(features, trials), fit_report(features, trials, spreads)
    assert not plain["fits_noise"]
    assert counted["fits_noise"]
    largest = max(float(np.max(s["jump"])) for s in spreads)
    assert largest > 5.0  # the sliding trial's start moves its jump by many noise units
    for block in ("jump", "torque", "impulse", "duration", "trace"):
        assert counted[block] <= plain[block] + 1e-12


def test_the_spread_on_two_processes_is_the_spread_on_one(sliding):
    """The trials split over two processes (a diagnosis's ``--jobs 2``) give the same spreads, in
    the trials' order."""
    trials, setting, truth = sliding
    one, two = start_spread(setting, truth, trials[:3], jobs=1), start_spread(setting, truth, trials[:3], jobs=2)
    assert len(one) == len(two) == 3
    for a, b in zip(one, two):
        assert a.keys() == b.keys()
        for name in a:
            np.testing.assert_array_equal(a[name], b[name])
