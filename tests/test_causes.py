"""Candidate causes map fitted numbers onto plant overrides (sim/causes.py)."""

import numpy as np
import pytest

from impactqp.sim.causes import CAUSE_NAMES, default_causes
from impactqp.sim.plant import PlantParameters


@pytest.mark.parametrize("cause", default_causes(), ids=lambda c: c.name)
def test_cause_round_trips_and_builds_valid_plants(cause):
    nominal = PlantParameters()
    lo, hi = cause.u_bounds()
    assert np.all(lo < hi) and len(lo) == len(cause.labels) == len(cause.lower)
    for f in (0.0, 0.3, 1.0):
        u = lo + f * (hi - lo)
        np.testing.assert_allclose(cause.to_u(cause.to_theta(u)), u, atol=1e-12)
        plant = cause.plant(nominal, u)
        overrides = cause.overrides(cause.to_theta(u))
        assert set(overrides) <= set(nominal.to_dict())
        PlantParameters.from_dict(overrides)  # valid plant-override file content: raises otherwise
        changed = {k for k, v in plant.to_dict().items() if v != nominal.to_dict()[k]}
        assert changed <= set(overrides)


@pytest.mark.parametrize("cause", default_causes(), ids=lambda c: c.name)
def test_overrides_read_back_and_realistic_ranges_lie_inside_the_bounds(cause):
    lo, hi = np.array(cause.realistic[0]), np.array(cause.realistic[1])
    assert np.all(np.array(cause.lower) <= lo) and np.all(lo < hi) and np.all(hi <= np.array(cause.upper))
    theta = 0.5 * (lo + hi)
    np.testing.assert_allclose(cause.theta_of(cause.overrides(theta)), theta)


def test_nominal_value_is_inside_the_bounds():
    nominal = PlantParameters()
    for cause in default_causes():
        theta = cause.nominal_theta(nominal)
        assert np.all(theta >= np.array(cause.lower)) and np.all(theta <= np.array(cause.upper))


def test_every_issue_cause_is_a_candidate():
    assert set(CAUSE_NAMES) == {"armature", "payload", "friction", "contact", "joint_damping", "servo_gain"}
