"""Sensor faults hidden in a small dataset: named, with the truth inside the interval
(sim/diagnosis with the sensor causes of sim/causes/sensor_causes.py)."""

import pytest
from diagnosis_checks import check_contract, inside

from conftest import JOINTS
from impactqp.sim.causes import ArmatureCause, JointDampingCause, cause_named
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

SMALL = {"postures": ["elbow_up", "elbow_left"], "speeds": [0.1, 0.18], "repeats": 2}


@pytest.mark.parametrize("name, overrides", [("delay", {"sensor_delay": 4.0})])
def test_a_sensor_fault_is_named_against_plant_causes_with_the_truth_inside(tmp_path, name, overrides):
    """The sensor fault competes with plant causes that could mimic it (damping lags like a
    delay, armature loads the torques); it alone is named, fits the noise, and every true value
    lies within its interval. (A torque offset per joint, seven profiled parameters, is a case of
    the bench's ``diagnose.accuracy`` rows, ``hidden_cases``.)"""
    generate_dataset(tmp_path, DatasetRequest(plant=PlantParameters(**overrides), seed=4, **SMALL))
    candidates = [ArmatureCause(JOINTS), JointDampingCause(JOINTS), cause_named(name, JOINTS)]
    result = diagnose(tmp_path, causes=candidates, jobs=2).summary()
    assert result["causes"] == [name] and result["explained"], result["steps"]
    assert result["fit"]["fits_noise"] and result["gain_over_floor"] >= 0.3
    truth = cause_named(name, JOINTS).theta_of(overrides)
    intervals = [p["interval"] for p in result["parameter_intervals"]]
    assert all(inside(v, i) for v, i in zip(truth, intervals)), (truth, intervals)
    check_contract(result)


def test_a_late_sensor_is_told_from_a_filter_and_never_read_as_damping(tmp_path):
    """dq and tau logged 2.5 samples late: read at two samples, the jump is matched by a 1.5 ms
    velocity filter or by joint damping; the velocity trace of the rise is not. With the delay
    among the candidates it alone is named, the truth inside its interval; without it nothing
    is explained and the misfit is named."""
    overrides = {"sensor_delay": 2.5}
    generate_dataset(tmp_path, DatasetRequest(plant=PlantParameters(**overrides), seed=6, **SMALL))
    mimics = [JointDampingCause(JOINTS), cause_named("velocity_filter", JOINTS)]
    result = diagnose(tmp_path, causes=[*mimics, cause_named("delay", JOINTS)], jobs=2).summary()
    assert result["causes"] == ["delay"] and result["explained"], result["steps"]
    (interval,) = [p["interval"] for p in result["parameter_intervals"]]
    assert inside(2.5, interval), interval
    assert result["nominal_fit"]["trace"] > result["fit"]["trace"]
    without = diagnose(tmp_path, causes=mimics, jobs=2).summary()
    assert not without["explained"] and without["causes"] == [] and not without["fit"]["fits_noise"]
    assert "residual is" in without["message"] and "as good as" not in without["message"]
