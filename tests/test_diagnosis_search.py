"""The search over sets of causes (sim/diagnosis/search.py): paths from the best first steps,
screened forward steps, refinements and backward removals, every step reported. The searches
of several hidden effects at once (pairs, the triple a greedy selection missed) are accuracy
goals: the bench's ``diagnose.accuracy`` rows."""

from diagnosis_checks import POSTURES, SPEEDS, check_contract, inside
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.sim.causes import ArmatureCause, JointDampingCause, TorqueOffsetCause, VelocityScaleCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.diagnosis.search import marked, search_step
from impactqp.sim.diagnosis.selection import EXPLAINED_GAIN
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

SMALL = {"postures": ["elbow_up", "elbow_left"], "speeds": [0.1, 0.18], "repeats": 2}


def test_nominal_plant_with_noise_is_not_explained(tmp_path):
    generate_dataset(tmp_path, DatasetRequest(postures=POSTURES, speeds=SPEEDS, tangential=[0.05], seed=11))
    result = diagnose(tmp_path, jobs=2).summary()
    assert not result["explained"] and result["causes"] == []
    assert max(c["gain"] for c in result["candidates"]) < EXPLAINED_GAIN
    assert result["steps"] and not result["steps"][0]["selected"]
    assert "No candidate" in result["message"] and "as good as" not in result["message"]
    assert result["nominal_fit"]["fits_noise"] and result["fit"]["fits_noise"]
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
