"""95 % intervals of the fitted parameters, open sides (sim/diagnosis/intervals.py)."""

import numpy as np
from diagnosis_checks import POSTURES
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import ArmatureCause, FrictionCause, PayloadCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.fitting import FittedCauses
from impactqp.sim.diagnosis.intervals import (
    SCAN_RESOLUTION,
    SCAN_TOLERANCE,
    bootstrap_intervals,
    excludes_nominal,
    parameter_owner,
    profile_crossing,
    profile_direction,
)
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters


def test_impacts_that_only_stick_leave_friction_open_above(tmp_path):
    """mu = 0.6 and a tangential speed of 0.03 m/s at v_n = 0.12 m/s: every impact sticks, so the
    data bound mu from below only; the message says so and names the trials that would settle
    it, and the value carried is the smallest mu with which every impact sticks."""
    request = DatasetRequest(plant=PlantParameters(friction=0.6), postures=POSTURES[:2], speeds=[0.12],
                             tangential=[0.03], seed=3)
    generate_dataset(tmp_path, request)
    result = diagnose(tmp_path, causes=[FrictionCause()]).summary()
    assert result["causes"] == ["friction"]
    low, high = result["intervals"]["friction"]
    assert high is None and low is not None and low <= 0.6
    # every mu above the stick/slip kink fits alike: the value carried is the near end of that
    # flat part, just above the closed end where the cost rises steeply (was 0.94, wherever
    # the fit stopped on the flat, with the closed end at 0.34)
    assert low <= result["parameters"]["friction"] <= low + 0.05 * (FrictionCause.upper[0] - low)
    assert [(o["parameter"], o["side"]) for o in result["open_sides"]] == [("friction coefficient", "above")]
    assert "cannot bound friction coefficient above" in result["message"]
    assert "tangential speeds of several mu times the normal speed" in result["message"]
    assert "normal speeds of 0.12 m/s" in result["message"]  # the dataset's own, not a constant


@given(st.floats(0.5, 1.5), st.floats(0.05, 0.45), st.floats(1.0, 1e4), st.floats(0.1, 100.0))
def test_a_crossing_beyond_a_kink_is_found_where_the_cost_crosses(start, kink, slope, threshold):
    """A profile flat from the fit down to a kink and straight and steep below it (friction
    between stick and slip): the crossing is at kink - threshold / slope, wherever the doubling
    steps land about the kink; a line drawn across the kink would put it at the flat end (the
    issue's 'at least 0.403' for a truth of 0.37 and a kink at 0.33). Found within the scan's
    resolution of the span, or within its tolerance on the cost."""
    span = 1.5
    crossing = kink - threshold / slope
    assume(abs(crossing) > 1e-9)  # not at the bound itself, where rounding decides
    samples = []

    def excess(x):
        samples.append(x)
        return max(0.0, slope * (kink - x))

    found = profile_crossing(excess, start, 0.0, span, threshold)
    if crossing < 0.0:
        assert found is None
        return
    assert abs(found - crossing) <= max(SCAN_RESOLUTION * span, SCAN_TOLERANCE * threshold / slope) + 1e-9
    assert all(0.0 <= x <= start for x in samples)


@given(st.floats(-1.0, 1.0), st.floats(0.1, 1e3), st.floats(0.1, 10.0), st.sampled_from([-1.0, 1.0]))
def test_a_smooth_profile_crosses_where_the_quadratic_does(start, curvature, threshold, side):
    """excess = a (x - x0)^2 crosses the threshold at x0 +- sqrt(threshold / a): found within the
    resolution, or where the excess is within the tolerance of the threshold; past the bound the
    side is open (None)."""
    span, limit = 4.0, start + side * 2.0
    crossing = start + side * np.sqrt(threshold / curvature)
    found = profile_crossing(lambda x: curvature * (x - start) ** 2, start, limit, span, threshold)
    assume(abs(abs(crossing - start) - 2.0) > 1e-9)  # not at the bound itself
    if abs(crossing - start) > 2.0:
        assert found is None
        return
    near = abs(found - crossing) <= SCAN_RESOLUTION * span + 1e-9
    assert near or abs(curvature * (found - start) ** 2 - threshold) <= SCAN_TOLERANCE * threshold * (1 + 1e-9)


def fitted_model(rng: np.random.Generator) -> FittedCauses:
    """Armature, payload and friction at random points of their bounds (7 parameters)."""
    model = FittedCauses()
    for cause in (ArmatureCause(JOINTS), PayloadCause(), FrictionCause()):
        lo, hi = cause.u_bounds()
        model = model.plus(cause, rng.uniform(lo, hi))
    return model


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_profile_direction_moves_one_parameter_and_refits_the_others(seed):
    """d_i = 1 and the others' least-squares normal equations hold: J_o^T J d = 0."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(30, 5))
    for index in range(5):
        d = profile_direction(J, index)
        others = [j for j in range(5) if j != index]
        assert d[index] == 1.0
        np.testing.assert_allclose(J[:, others].T @ (J @ d), 0.0, atol=1e-9)


def test_parameter_owner_inverts_the_concatenation_of_the_vectors():
    model = fitted_model(np.random.default_rng(0))
    owners = [parameter_owner(model, i) for i in range(len(model.vector()))]
    assert owners == [(k, j) for k, u in enumerate(model.u) for j in range(len(u))]
    for i, (k, j) in enumerate(owners):
        assert model.vector()[i] == model.u[k][j]


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_bootstrap_intervals_hold_the_fit_and_stay_within_the_bounds(seed):
    rng = np.random.default_rng(seed)
    model = fitted_model(rng)
    sizes = [14, 18, 14, 18, 18]
    J = rng.normal(size=(sum(sizes), len(model.vector())))
    r = rng.normal(size=sum(sizes))
    intervals = bootstrap_intervals(model, r, J, sizes)
    lo, hi = model.bounds()
    u = model.vector()
    assert intervals.shape == (len(u), 2)
    assert np.all(lo <= intervals[:, 0]) and np.all(intervals[:, 0] <= u)
    assert np.all(u <= intervals[:, 1]) and np.all(intervals[:, 1] <= hi)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 6))
def test_a_bootstrap_resample_of_trials_that_do_not_move_a_parameter_widens_nothing(seed, sliding):
    """Friction seen only in ``sliding`` of 8 trials (the others' Jacobian column is rounding,
    1e-11): each sliding trial k alone fits mu* - e_k (its residuals J_k e_k), so every
    resample that determines mu fits a weighted mean of the drawn -e_k, and the interval stays
    within the t-widened hull of the e_k. A resample of non-sliding trials alone (a few in
    1000) steps 1e10 to a bound of the fit: the interval reached across the nominal mu (issue
    32's friction seeds, [0.077, 0.542] for a fit of 0.310 +- 0.001)."""
    rng = np.random.default_rng(seed)
    model = FittedCauses().plus(FrictionCause(), np.array([0.31]))
    sizes = [40] * 8
    J = 1e-11 * rng.normal(size=(sum(sizes), 1))
    r = rng.normal(size=sum(sizes))
    e = 1e-3 * rng.normal(size=sliding)
    for k in range(sliding):
        rows = slice(40 * (8 - sliding + k), 40 * (8 - sliding + k + 1))
        J[rows, 0] = 1000.0 * rng.uniform(0.5, 2.0, size=40)
        r[rows] = J[rows, 0] * e[k]
    low, high = bootstrap_intervals(model, r, J, sizes)[0]
    reach = 3.0 * np.max(np.abs(e))  # t_0.975(7) sqrt(8 / 7) = 2.52 times a spread within the hull
    assert 0.31 - reach <= low <= 0.31 <= high <= 0.31 + reach


@given(st.floats(0.0, 1.5), st.floats(0.0, 0.5), st.floats(0.0, 0.5), st.booleans())
def test_a_cause_is_supported_only_when_an_interval_excludes_its_nominal_value(value, below, above, open_low):
    """Friction about ``value``: supported exactly when the nominal coefficient lies outside
    [value - below, value + above] (an open side reaches every value on it)."""
    cause = FrictionCause()
    model = FittedCauses((cause,), (cause.to_u(np.array([value])),))
    low = None if open_low else value - below
    nominal = float(cause.nominal_theta(PlantParameters())[0])
    expected = not ((low is None or low <= nominal) and nominal <= value + above)
    assert excludes_nominal(model, [[[low, value + above]]], PlantParameters()) == [expected]


def test_a_side_open_down_to_a_floor_at_or_above_the_nominal_reads_negligible():
    """An armature open down to its fit's floor (1e-3 kg m^2 on a log scale; nominal 0) is
    negligible, as a payload open down to 0 is: no trials are advised (before: "cannot bound
    armature joints 1-4 below: more trials"). A servo gain open down to its floor, below the
    nominal 5 rad/s, is a real open side with the trials that would settle it."""
    from types import SimpleNamespace

    from impactqp.sim.causes import ServoGainCause
    from impactqp.sim.diagnosis.intervals import open_sides

    armature, servo, payload = ArmatureCause(JOINTS), ServoGainCause(), PayloadCause()
    model = FittedCauses((armature, servo, payload), (armature.u_bounds()[0], servo.u_bounds()[0],
                                                    payload.to_u(np.array([0.0, 0.0, 0.0, -0.1]))))
    intervals = [[(None, 0.01), (None, 0.02)], [(None, 3.0)], [(None, 0.2), (-0.1, 0.1), (-0.1, 0.1), (-0.3, 0.05)]]
    sides = open_sides(model, intervals, [SimpleNamespace(reference_speed=0.1)], PlantParameters().for_joints(JOINTS))
    assert [(o["cause"], o["negligible"], o["trials_needed"] == "") for o in sides] == [
        ("armature", True, True), ("armature", True, True), ("servo_gain", False, False), ("payload", True, True)]
