"""Candidate causes map fitted numbers onto plant overrides (sim/causes/: the interface, the plant and the sensor causes)."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import (
    CAUSE_NAMES,
    ArmatureCause,
    FixedParameters,
    cause_named,
    JointDampingCause,
    JointVelocityScaleCause,
    VelocityScaleCause,
    PayloadCause,
    default_causes,
    group_means,
    joint_groups,
    per_group,
)
from impactqp.sim.plant import PlantParameters
from impactqp.sim.sensor import velocity_scales
from impactqp.controller.model.validation import BadInputError


@pytest.mark.parametrize("cause", default_causes(JOINTS) + [JointVelocityScaleCause(JOINTS)], ids=lambda c: c.name + str(len(c.labels)))
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


@pytest.mark.parametrize("cause", default_causes(JOINTS), ids=lambda c: c.name)
def test_overrides_read_back_and_realistic_ranges_lie_inside_the_bounds(cause):
    lo, hi = np.array(cause.realistic[0]), np.array(cause.realistic[1])
    assert np.all(np.array(cause.lower) <= lo) and np.all(lo < hi) and np.all(hi <= np.array(cause.upper))
    theta = 0.5 * (lo + hi)
    np.testing.assert_allclose(cause.theta_of(cause.overrides(theta)), theta)


def test_nominal_value_is_inside_the_bounds():
    nominal = PlantParameters()
    for cause in default_causes(JOINTS):
        theta = cause.nominal_theta(nominal)
        assert np.all(theta >= np.array(cause.lower)) and np.all(theta <= np.array(cause.upper))


def test_every_issue_cause_is_a_candidate():
    assert set(CAUSE_NAMES) == {
        "armature", "payload", "friction", "contact", "joint_damping", "joint_friction", "servo_gain",
        "delay", "velocity_scale", "torque_offset", "velocity_filter",
    }


def test_sensor_causes_change_only_sensor_keys_and_leave_the_physics_alone():
    nominal = PlantParameters()
    for name in ("delay", "velocity_scale", "torque_offset", "velocity_filter"):
        cause = cause_named(name, JOINTS)
        lo, hi = cause.u_bounds()
        plant = cause.plant(nominal, 0.3 * lo + 0.7 * hi)
        assert all(key.startswith("sensor_") for key in cause.overrides(cause.to_theta(lo)))
        assert plant.physical() == nominal and plant != nominal


@given(st.lists(st.floats(0.0, 10.0, allow_nan=False), min_size=2, max_size=2), st.integers(2, 40))
def test_group_values_round_trip_for_any_joint_count(values, joints):
    """The groups partition the joints, the shoulder's and elbow's first (ceil(n / 2): the
    Panda's 1-4, the UR5's 1-3); one value per group spreads and averages back."""
    groups = joint_groups(joints)
    assert [j for g in groups for j in g] == list(range(joints)) and len(groups[0]) == (joints + 1) // 2
    spread = per_group(values, joints)
    assert len(spread) == joints and all(spread[j] == values[k] for k, g in enumerate(groups) for j in g)
    np.testing.assert_allclose(group_means(spread), values)


def test_a_six_joint_arm_gets_its_own_groups_and_labels():
    cause = ArmatureCause(6)
    assert cause.labels == ("armature joints 1-3 (kg m^2)", "armature joints 4-6 (kg m^2)")
    assert cause.overrides([0.4, 0.1])["armature"] == [0.4] * 3 + [0.1] * 3


def test_armature_and_damping_are_fitted_per_joint_group():
    for cause in (ArmatureCause(JOINTS), JointDampingCause(JOINTS)):
        key = next(iter(cause.overrides(np.array([1.0, 1.0]))))
        values = cause.overrides(np.array([0.7, 0.2]))[key]
        assert values == [0.7] * 4 + [0.2] * 3


def test_payload_fits_mass_and_centre_of_mass():
    cause = PayloadCause()
    theta = np.array([1.2, 0.01, -0.02, -0.05])
    overrides = cause.overrides(theta)
    assert overrides == {"payload_mass": 1.2, "payload_com": [0.01, -0.02, -0.05]}
    plant = cause.plant(PlantParameters(), cause.to_u(theta))
    assert plant.payload_mass == 1.2 and plant.payload_com == (0.01, -0.02, -0.05)
    assert all(len(p) == 4 for p in cause.grid(PlantParameters()))


@pytest.mark.parametrize("cause", default_causes(JOINTS), ids=lambda c: c.name)
def test_grid_starts_at_the_nominal_value_inside_the_bounds(cause):
    lo, hi = cause.u_bounds()
    grid = cause.grid(PlantParameters())
    np.testing.assert_allclose(grid[0], cause.to_u(cause.nominal_theta(PlantParameters())))
    assert all(np.all(lo - 1e-12 <= p) and np.all(p <= hi + 1e-12) for p in grid)
    for j in range(len(cause.labels)):
        for side in ("below", "above"):
            assert cause.settling_trials(j, side, float(cause.to_theta(grid[0])[j]), np.array([0.1, 0.2])).strip()


def test_a_cause_is_found_by_its_name_and_an_unknown_name_is_bad_input():
    for name in CAUSE_NAMES:
        assert cause_named(name, JOINTS).name == name
    with pytest.raises(BadInputError, match="the cause = 'gravity'; choose from armature"):
        cause_named("gravity", JOINTS)


@given(st.floats(0.7, 1.4))
def test_the_joint_velocity_scale_refines_the_global_one_and_starts_where_it_ends(scale):
    """The refinement keeps the cause's name, and the global scale read as joint scales builds the
    same sensor (every joint at the global value)."""
    coarse = VelocityScaleCause(JOINTS)
    finer = coarse.refined()
    assert isinstance(finer, JointVelocityScaleCause) and finer.name == coarse.name
    theta = finer.theta_of(coarse.overrides(np.array([scale])))
    np.testing.assert_allclose(theta, scale)
    a = PlantParameters(**coarse.overrides(np.array([scale])))
    b = PlantParameters(**finer.overrides(theta))
    np.testing.assert_allclose(velocity_scales(a, JOINTS), velocity_scales(b, JOINTS))
    assert all(c.refined() is None for c in default_causes(JOINTS) if c.name != "velocity_scale")


@given(st.lists(st.floats(0.7, 1.4), min_size=JOINTS, max_size=JOINTS), st.sets(st.integers(0, JOINTS - 1), max_size=JOINTS - 1))
def test_held_parameters_stay_at_their_values_and_the_free_ones_round_trip(scales, held):
    """Joint velocity scales with some held at 1: the plant gets the free ones as given and the
    held ones at 1; theta reads back the free ones; bounds, labels and the grid are the free
    ones' (every grid point of the cause, restricted)."""
    cause = JointVelocityScaleCause(JOINTS)
    fixed = FixedParameters(cause, {j: 1.0 for j in held})
    free = [j for j in range(JOINTS) if j not in held]
    theta = np.array(scales)[free]
    expected = np.ones(JOINTS)
    expected[free] = theta
    plant = fixed.plant(PlantParameters(), fixed.to_u(theta))
    assert np.allclose(velocity_scales(plant, JOINTS), expected)
    assert np.allclose(fixed.theta_of(fixed.overrides(theta)), theta)
    assert fixed.labels == tuple(cause.labels[j] for j in free) and fixed.name == cause.name
    assert np.allclose(fixed.u_bounds(), np.array(cause.u_bounds())[:, free])
    assert [len(u) for u in fixed.grid(PlantParameters())] == [len(free)] * len(cause.grid(PlantParameters()))
    assert np.allclose(fixed.nominal_theta(PlantParameters()), 1.0)
