"""The search over sets of causes (sim/diagnosis/search.py): paths from the best first steps,
screened forward steps, refinements and backward removals, every step reported."""

import numpy as np
from diagnosis_checks import POSTURES, SPEEDS, check_contract, inside, tolerance
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import (
    ArmatureCause,
    FrictionCause,
    JointDampingCause,
    PayloadCause,
    TorqueOffsetCause,
    VelocityScaleCause,
    per_group,
)
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.noise import FIT_LIMIT
from impactqp.sim.diagnosis.search import marked, search_step
from impactqp.sim.diagnosis.selection import EXPLAINED_GAIN, STEP_GAIN
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

SMALL = {"postures": ["elbow_up", "elbow_left"], "speeds": [0.1, 0.18], "repeats": 2}


def test_two_hidden_effects_are_both_named_each_within_its_interval(tmp_path):
    """Armature per group and a payload hidden at once: both are named, refitted jointly, and
    every hidden value (armature per group, payload mass and CoM) lies within its interval."""
    truth = {"armature": per_group((0.6, 0.15), JOINTS), "payload_mass": 1.0, "payload_com": [0.01, -0.01, -0.06]}
    request = DatasetRequest(plant=PlantParameters(**truth), postures=POSTURES, speeds=SPEEDS, seed=7)
    generate_dataset(tmp_path, request, jobs=2)
    result = diagnose(tmp_path, jobs=2).summary()
    assert sorted(result["causes"]) == ["armature", "payload"], result["steps"]
    check_contract(result)
    for key, value in truth.items():
        pairs = result["intervals"][key]
        values, pairs = (value, pairs) if isinstance(value, list) else ([value], [pairs])
        assert all(inside(v, pair) for v, pair in zip(values, pairs)), key
    payload = PayloadCause()
    theta = payload.theta_of(truth)
    assert np.all(np.abs(payload.theta_of(result["parameters"]) - theta) <= tolerance(payload, theta))
    assert [s["selected"] and s["gain"] >= STEP_GAIN for s in result["steps"][:2]] == [True, True]


def test_nominal_plant_with_noise_is_not_explained(tmp_path):
    generate_dataset(tmp_path, DatasetRequest(postures=POSTURES, speeds=SPEEDS, tangential=[0.05], seed=11))
    result = diagnose(tmp_path, jobs=2).summary()
    assert not result["explained"] and result["causes"] == []
    assert max(c["gain"] for c in result["candidates"]) < EXPLAINED_GAIN
    assert result["steps"] and not result["steps"][0]["selected"]
    assert "No candidate" in result["message"] and "as good as" not in result["message"]
    assert result["nominal_fit"]["fits_noise"] and result["fit"]["fits_noise"]
    check_contract(result)


def test_three_hidden_effects_that_a_greedy_selection_missed_are_named(tmp_path):
    """Armature, a payload and friction hidden at once, with tangential speeds: the greedy
    selection took armature, then friction, and its grid screen then dropped the payload (one
    run, docs/diagnosis.md). The search names all three, fits the noise and recovers every
    value (the armature's interval missed its truth by 0.2 % in one run: not asserted)."""
    truth = {"armature": per_group((0.3, 0.15), JOINTS), "payload_mass": 0.4, "payload_com": [0.01, 0.0, -0.05],
             "friction": 0.4}
    request = DatasetRequest(plant=PlantParameters(**truth), tangential=[0.3, 0.6], seed=8, **SMALL)
    generate_dataset(tmp_path, request, jobs=2)
    result = diagnose(tmp_path, jobs=2).summary()
    assert sorted(result["causes"]) == ["armature", "friction", "payload"] and result["explained"], result["steps"]
    assert result["fit"]["fits_noise"]
    for cause in (ArmatureCause(JOINTS), PayloadCause(), FrictionCause()):
        value = cause.theta_of(truth)
        assert np.all(np.abs(cause.theta_of(result["parameters"]) - value) <= tolerance(cause, value)), cause.name
    check_contract(result)


def test_three_large_hidden_effects_that_mask_each_other_are_named_together(tmp_path):
    """Armature, payload and friction hidden at once, each large (a draw of the coverage study,
    its seed 6005, with the study's 2 postures x (2 normal + 2 tangential speeds), one
    repeat): no candidate alone gains STEP_GAIN held out (each fits a part of the others), so
    the search stopped before any path and named nothing. The three together, each started
    from its fit alone, reach the noise: all three are named, with intervals that hold every
    truth. The three hidden causes are the only candidates (the coverage study's setting)."""
    truth = {"armature": per_group((1.25, 0.06), JOINTS), "payload_mass": 1.14,
             "payload_com": [0.016, -0.012, -0.027], "friction": 0.62}
    request = DatasetRequest(plant=PlantParameters(**truth), postures=SMALL["postures"], speeds=SMALL["speeds"],
                             tangential=[0.3, 0.6], seed=6005)
    generate_dataset(tmp_path, request, jobs=2)
    causes = [ArmatureCause(JOINTS), PayloadCause(), FrictionCause()]
    result = diagnose(tmp_path, causes=causes, jobs=2).summary()
    assert max(c["gain"] for c in result["candidates"]) < STEP_GAIN  # each alone is masked
    assert sorted(result["causes"]) == ["armature", "friction", "payload"] and result["explained"], result["steps"]
    rows = result["parameter_intervals"]
    for cause in causes:
        intervals = [row["interval"] for row in rows if row["cause"] == cause.name]
        assert all(inside(v, i) for v, i in zip(cause.theta_of(truth), intervals)), (cause.name, intervals)
    check_contract(result)


def test_one_joints_velocity_scale_is_named_with_that_joint(tmp_path):
    """Joint 4's dq logged 12 % too large: the global velocity scale is chosen first, then
    refined per joint; joint 4's interval holds the truth and excludes 1, and joint 4 is the one
    that moved: every other joint's value stays within 10 % of 1 and at most one of their six
    95 % intervals misses 1 (all six hold it only about 0.95^6 = 74 % of the time)."""
    joints = [1.0, 1.0, 1.0, 1.12, 1.0, 1.0, 1.0]
    plant = PlantParameters(sensor_joint_velocity_scale=joints)
    generate_dataset(tmp_path, DatasetRequest(plant=plant, seed=6, **SMALL))
    candidates = [ArmatureCause(JOINTS), JointDampingCause(JOINTS), TorqueOffsetCause(JOINTS), VelocityScaleCause(JOINTS)]
    result = diagnose(tmp_path, causes=candidates, jobs=2).summary()
    assert result["causes"] == ["velocity_scale"] and result["explained"], result["steps"]
    scale = next(c for c in result["candidates"] if c["cause"] == "velocity_scale")
    assert "sensor_joint_velocity_scale" in scale["parameters"]  # refined in the first step
    intervals = [p["interval"] for p in result["parameter_intervals"]]
    assert len(intervals) == JOINTS and inside(1.12, intervals[3]) and not inside(1.0, intervals[3])
    values = [p["value"] for p in result["parameter_intervals"]]
    others = [j for j in range(JOINTS) if j != 3]
    assert all(abs(values[j] - 1.0) < 0.1 for j in others), values
    assert sum(not inside(1.0, intervals[j]) for j in others) <= 1, intervals
    check_contract(result)


def test_a_second_cause_behind_a_model_that_fits_the_noise_is_named(tmp_path):
    """Joint damping on joints 1-4 and joint 6's dq logged 5 % too large (the issue's case):
    damping alone fits the noise in every block, but joint 6's jump reads about 5.7 noise units
    (within the channel limit, beyond a block's): the search goes on, adds the velocity scale
    per joint (a significant held-out gain) and names both; each hidden value lies within its
    interval, joint 6's scale excludes 1, and the other joints' scales, whose intervals hold 1,
    are dropped (held at 1). Before: damping alone was named, joint 6 left in its residual."""
    truth = {"joint_damping": [1.0] * 4 + [0.0] * 3, "sensor_joint_velocity_scale": [1, 1, 1, 1, 1, 1.05, 1]}
    generate_dataset(tmp_path, DatasetRequest(plant=PlantParameters(**truth), seed=4, **SMALL), jobs=2)
    result = diagnose(tmp_path, causes=[JointDampingCause(JOINTS), VelocityScaleCause(JOINTS)], jobs=2).summary()
    assert sorted(result["causes"]) == ["joint_damping", "velocity_scale"] and result["explained"], result["steps"]
    assert result["fit"]["fits_noise"] and result["fit"]["worst_channel"]["value"] <= FIT_LIMIT
    rows = {p["parameter"]: p for p in result["parameter_intervals"]}
    assert inside(1.0, rows["joint damping joints 1-4 (N m s/rad)"]["interval"])
    scale = rows["velocity scale joint 6"]
    assert inside(1.05, scale["interval"]) and not inside(1.0, scale["interval"])
    for j in (1, 2, 3, 4, 5, 7):
        row = rows[f"velocity scale joint {j}"]
        assert inside(1.0, row["interval"]) and row["value"] == 1.0, row
    check_contract(result)


@settings(deadline=None)  # a loaded machine
@given(st.lists(st.sampled_from(["a", "b", "c"]), min_size=1, max_size=6), st.data())
def test_selected_marks_the_last_accepted_addition_of_each_final_cause(names, data):
    steps = [search_step(data.draw(st.sampled_from(["add", "remove", "refine"])), n, 1.0, 0.3,
                         data.draw(st.booleans()), 0) for n in names]
    added = [s["cause"] for s in steps if s["action"] == "add" and s["accepted"]]
    final = list(dict.fromkeys(reversed(added)))[::-1]
    out = marked(steps, final)
    assert sum(s["selected"] for s in out) == len(final)
    for cause in final:
        last = max(i for i, s in enumerate(out) if s["cause"] == cause and s["action"] == "add" and s["accepted"])
        assert out[last]["selected"]
    assert [{k: v for k, v in s.items() if k != "selected"} for s in out] == [
        {k: v for k, v in s.items() if k != "selected"} for s in steps]
