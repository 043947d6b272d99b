"""Dataset format: atomic writer and typed reader (the checks: test_dataset_check.py)."""

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot import TOOL_TIP_OFFSET
from impactqp.controller.model.tool_description import TOOLS
from impactqp.controller.measured.dataset import (
    FORMAT,
    DatasetError,
    DatasetHeader,
    TrialEntry,
    read_dataset,
)
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.dataset_writer import DatasetWriter
from impactqp.controller.measured.impact import measure_impact
from impactqp.sim.plant import PlantParameters

from conftest import G1_HEADER, DATASET_HEADER, JOINTS, dataset_entry, g1_dataset, g1_log


def test_round_trip(dataset, dataset_logs):
    data = read_dataset(dataset)
    assert data.header.to_dict() == DATASET_HEADER.to_dict()
    fast, slow = data.trials
    assert fast.entry == dataset_entry("fast", 0.15, dataset_logs[0.15])
    for read, original in ((fast.log, dataset_logs[0.15]), (slow.log, dataset_logs[0.1])):
        for name in ("t", "q", "dq", "tau", "dq_cmd"):
            np.testing.assert_allclose(getattr(read, name), getattr(original, name), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.log.force, dataset_logs[0.15].force, rtol=1e-9, atol=1e-9)
    assert not slow.log.has_force
    # the impact measured from the files is the one measured from the simulation
    np.testing.assert_allclose(measure_impact(fast.log).dq_jump, measure_impact(dataset_logs[0.15]).dq_jump, atol=1e-8)


def test_manifest_holds_what_a_robot_log_holds_and_no_plant_parameter(dataset):
    manifest = json.loads((dataset / "dataset.json").read_text())
    assert manifest["format"] == FORMAT and manifest["robot"] == "panda"
    assert manifest["tool"] == TOOLS["impact_tip"].as_dict()
    text = (dataset / "dataset.json").read_text()
    for name in PlantParameters().to_dict():
        if name != "friction":  # the surface's friction is part of the format
            assert name not in text
    header = (dataset / "fast.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["t", "q1"] and header[-1] == f"dq_cmd{JOINTS}" and len(header) == 1 + 4 * JOINTS
    assert (dataset / "fast_force.csv").read_text().startswith("t,fx,fy,fz\n")
    assert not [p for p in dataset.iterdir() if p.name.endswith(".tmp")]


def test_an_unknown_friction_stays_out_of_the_manifest(tmp_path, dataset_logs):
    """A header without a known friction (a real robot's log) writes no ``surface.friction`` and
    reads back as such; the surface then holds the default coefficient."""
    from dataclasses import replace

    unknown = replace(DATASET_HEADER, friction_known=False)
    DatasetWriter(tmp_path, unknown).add_trial(dataset_entry("fast", 0.15, dataset_logs[0.15]), dataset_logs[0.15])
    manifest = json.loads((tmp_path / "dataset.json").read_text())
    assert set(manifest["surface"]) == {"point", "normal"}
    header = read_dataset(tmp_path).header
    assert header.friction_known is False and header.to_dict() == unknown.to_dict()
    assert header.surface.friction == DEFAULT_WALL.friction
    assert validate(tmp_path) == {"dataset": [], "fast": []}


def test_a_declared_encoder_step_is_written_and_read_back(tmp_path, dataset_logs):
    """The optional ``encoder_step`` (rad/s of dq per joint) round-trips; without it the header
    declares none and the manifest has no such key."""
    steps = tuple(0.001 * (j + 1) for j in range(JOINTS))
    quantised = replace(DATASET_HEADER, encoder_step=steps)
    DatasetWriter(tmp_path, quantised).add_trial(dataset_entry("fast", 0.15, dataset_logs[0.15]), dataset_logs[0.15])
    assert json.loads((tmp_path / "dataset.json").read_text())["encoder_step"] == list(steps)
    header = read_dataset(tmp_path).header
    assert header.encoder_step == steps and header.to_dict() == quantised.to_dict()
    assert DATASET_HEADER.encoder_step is None and "encoder_step" not in DATASET_HEADER.to_dict()


def _rewrite_manifest(directory, edit):
    path = directory / "dataset.json"
    manifest = json.loads(path.read_text())
    edit(manifest)
    path.write_text(json.dumps(manifest))


@pytest.mark.parametrize("robot", ["panda", "fr3"])
def test_a_first_version_manifest_reads_as_the_impact_tip(tmp_path, dataset_logs, robot):
    writer = DatasetWriter(tmp_path, DatasetHeader(TOOLS["impact_tip"], DEFAULT_WALL, 1e-3, robot=robot))
    writer.add_trial(TrialEntry("fast", "fast.csv", 0.15), dataset_logs[0.15])
    _rewrite_manifest(tmp_path, lambda m: m.__setitem__(
        "tool", {"frame": f"{robot}_hand", "contact_point": [0.0, 0.0, TOOL_TIP_OFFSET]}))
    header = read_dataset(tmp_path).header
    assert header.tool is TOOLS["impact_tip"] and header.robot == robot
    assert header.choice.same_as(header.choice.of(robot, "impact_tip"))
    _rewrite_manifest(tmp_path, lambda m: m["tool"].__setitem__("contact_point", [0.0, 0.0, 0.2]))
    with pytest.raises(DatasetError, match="is not the impact tool"):
        read_dataset(tmp_path)


@pytest.mark.parametrize("tool", ["franka_hand", "pad"])
def test_the_manifest_records_and_reads_back_the_full_tool(tmp_path, dataset_logs, tool):
    header = DatasetHeader(TOOLS[tool], DEFAULT_WALL, 1e-3, robot="fr3")
    DatasetWriter(tmp_path, header).add_trial(TrialEntry("fast", "fast.csv", 0.15), dataset_logs[0.15])
    read = read_dataset(tmp_path).header
    assert read.robot == "fr3" and read.tool.as_dict() == TOOLS[tool].as_dict()
    _rewrite_manifest(tmp_path, lambda m: m["tool"].__setitem__("mass", -1.0))
    with pytest.raises(DatasetError, match="tool: the tool mass"):
        read_dataset(tmp_path)


# ---------------------------------------------------------------------------- the G1
G1_ARRAYS = ("t", "q", "dq", "tau", "dq_cmd", "base", "force_t", "force")


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-6, 1e3))
def test_a_g1_trial_reads_back_as_written(tmp_path_factory, seed, scale):
    """Write -> read gives back every logged array to the CSV's 10 significant digits, the header
    (robot g1, its contact frame, the wall) and the entry."""
    directory = tmp_path_factory.mktemp("g1")
    log = g1_log(seed, scale)
    entry = TrialEntry("g", "g.csv", 0.3, force_file="g_force.csv", posture="parallel")
    DatasetWriter(directory, G1_HEADER).add_trial(entry, log)
    data = read_dataset(directory)
    assert data.header.to_dict() == G1_HEADER.to_dict() and data.trials[0].entry == entry
    for name in G1_ARRAYS:
        np.testing.assert_allclose(getattr(data.trials[0].log, name), getattr(log, name), rtol=1e-9, atol=0.0)
    manifest = json.loads((directory / "dataset.json").read_text())
    assert manifest["robot"] == "g1" and manifest["tool"] == {"frame": "right_palm_contact", "contact_point": [0, 0, 0]}


def test_a_g1_log_without_its_base_state_is_not_written(tmp_path):
    log = replace(g1_log(0), base=np.zeros((0, 13)))
    with pytest.raises(DatasetError, match="base state"):
        DatasetWriter(tmp_path, G1_HEADER).add_trial(TrialEntry("g", "g.csv", 0.3), log)
    assert not list(tmp_path.iterdir())


def _drop_column(path, name):
    lines = [line.split(",") for line in path.read_text().splitlines()]
    index = lines[0].index(name)
    path.write_text("\n".join(",".join(x[:index] + x[index + 1:]) for x in lines) + "\n")


@pytest.mark.parametrize("damage, message", [
    (lambda p: _drop_column(p, "base_qw"), "lacks the column"),
    (lambda p: _drop_column(p, "dq_cmd29"), "lacks the column"),
    (lambda p: p.write_text(p.read_text().replace("base_x", "base_X", 1)), "lacks the column"),
    (lambda p: p.write_text(p.read_text()[: len(p.read_text()) // 2]), "values per row|not a numeric CSV"),
    (lambda p: p.write_text(p.read_text().splitlines()[0] + "\n"), "holds no samples"),
    (lambda p: p.write_bytes(b"\x00\xff" * 50), "not a numeric CSV"),
    (lambda p: p.write_text(p.read_text().replace("\n0,", "\nnan,", 1)), "not a numeric CSV|NaN"),
])
def test_a_damaged_g1_csv_is_one_line_of_bad_input(tmp_path, damage, message):
    g1_dataset(tmp_path)
    damage(tmp_path / "g.csv")
    with pytest.raises(DatasetError, match=message) as error:
        read_dataset(tmp_path)
    assert "\n" not in str(error.value)
    problems = validate(tmp_path)
    assert problems["dataset"] == [] and len(problems["g"]) == 1 and "\n" not in problems["g"][0]


def test_a_g1_dataset_is_no_arm_choice(tmp_path):
    g1_dataset(tmp_path)
    header = read_dataset(tmp_path).header
    with pytest.raises(DatasetError, match="g1 dataset"):
        header.choice


@pytest.mark.parametrize("impact_time", [float("nan"), float("inf"), -0.5])
def test_an_impact_time_that_is_no_time_in_the_log_is_refused(tmp_path, dataset_logs, impact_time):
    """A trial's declared ``impact_time`` must be a finite time >= 0 s (NaN compared false with
    every bound and passed before)."""
    writer = DatasetWriter(tmp_path, DATASET_HEADER)
    writer.add_trial(TrialEntry("fast", "fast.csv", 0.15), dataset_logs[0.15])
    _rewrite_manifest(tmp_path, lambda m: m["trials"][0].__setitem__("impact_time", impact_time))
    with pytest.raises(DatasetError, match="impact_time must be a finite time >= 0 s") as error:
        read_dataset(tmp_path)
    assert "\n" not in str(error.value)


def test_a_tangential_velocity_off_the_wall_s_plane_is_refused(tmp_path, dataset_logs):
    """``reference_tangential_velocity`` is the approach's velocity in the wall's plane: one with a
    component along the normal (here all of it) is refused by reading and by ``validate``."""
    writer = DatasetWriter(tmp_path, DATASET_HEADER)
    writer.add_trial(TrialEntry("fast", "fast.csv", 0.15), dataset_logs[0.15])
    along = DATASET_HEADER.surface.normal * 0.05
    _rewrite_manifest(tmp_path, lambda m: m["trials"][0].__setitem__("reference_tangential_velocity", along.tolist()))
    with pytest.raises(DatasetError, match="must lie in the wall's plane, its component along the normal is 0.05 m/s"):
        read_dataset(tmp_path)
    assert any("wall's plane" in p for p in validate(tmp_path)["dataset"])
