"""Dataset format: atomic writer, typed reader, read-only validation."""

import hashlib
import json
import re

import numpy as np
import pytest

from impactqp.controller.model.postures import DEFAULT_WALL, POSTURES, Surface
from impactqp.controller.model.robot import TOOL_TIP_OFFSET, PandaModel
from impactqp.controller.model.tool_description import TOOLS
from impactqp.controller.measured.dataset import (
    FORMAT,
    DatasetError,
    DatasetHeader,
    DatasetWriter,
    TrialEntry,
    read_dataset,
)
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.impact import measure_impact
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.scene import build_scene

ROBOT = PandaModel()
HEADER = DatasetHeader(TOOLS["impact_tip"], DEFAULT_WALL, 1e-3)


@pytest.fixture(scope="module")
def logs():
    scene = build_scene(plant=PlantParameters(armature=[0.2] * 7))
    return {
        speed: run_approach(scene, ROBOT, TrialSpec("elbow_left", POSTURES["elbow_left"].q, speed, after_contact=0.05))
        for speed in (0.1, 0.15)
    }


def entry(name, speed, log, force=True):
    return TrialEntry(
        id=name,
        file=f"{name}.csv",
        force_file=f"{name}_force.csv" if force else None,
        reference_normal_speed=speed,
        reference_tangential_velocity=(0.0, 0.0, 0.0),
        posture="elbow_left",
        impact_time=measure_impact(log).t_contact_start,
    )


@pytest.fixture()
def dataset(tmp_path, logs):
    writer = DatasetWriter(tmp_path, HEADER)
    writer.add_trial(entry("fast", 0.15, logs[0.15]), logs[0.15])
    writer.add_trial(entry("slow", 0.1, logs[0.1], force=False), logs[0.1])
    return tmp_path


def digest(directory):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.iterdir())}


def test_round_trip(dataset, logs):
    data = read_dataset(dataset)
    assert data.header.to_dict() == HEADER.to_dict()
    fast, slow = data.trials
    assert fast.entry == entry("fast", 0.15, logs[0.15])
    for read, original in ((fast.log, logs[0.15]), (slow.log, logs[0.1])):
        for name in ("t", "q", "dq", "tau", "dq_cmd"):
            np.testing.assert_allclose(getattr(read, name), getattr(original, name), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.log.force, logs[0.15].force, rtol=1e-9, atol=1e-9)
    assert not slow.log.has_force
    # the impact measured from the files is the one measured from the simulation
    np.testing.assert_allclose(measure_impact(fast.log).dq_jump, measure_impact(logs[0.15]).dq_jump, atol=1e-8)


def test_manifest_holds_what_a_robot_log_holds_and_no_plant_parameter(dataset):
    manifest = json.loads((dataset / "dataset.json").read_text())
    assert manifest["format"] == FORMAT and manifest["robot"] == "panda"
    assert manifest["tool"] == TOOLS["impact_tip"].as_dict()
    text = (dataset / "dataset.json").read_text()
    for name in PlantParameters().to_dict():
        if name != "friction":  # the surface's friction is part of the format
            assert name not in text
    header = (dataset / "fast.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["t", "q1"] and header[-1] == "dq_cmd7" and len(header) == 29
    assert (dataset / "fast_force.csv").read_text().startswith("t,fx,fy,fz\n")
    assert not [p for p in dataset.iterdir() if p.name.endswith(".tmp")]


def test_an_unknown_friction_stays_out_of_the_manifest(tmp_path, logs):
    """A header without a known friction (a real robot's log) writes no ``surface.friction`` and
    reads back as such; the surface then holds the default coefficient."""
    from dataclasses import replace

    unknown = replace(HEADER, friction_known=False)
    DatasetWriter(tmp_path, unknown).add_trial(entry("fast", 0.15, logs[0.15]), logs[0.15])
    manifest = json.loads((tmp_path / "dataset.json").read_text())
    assert set(manifest["surface"]) == {"point", "normal"}
    header = read_dataset(tmp_path).header
    assert header.friction_known is False and header.to_dict() == unknown.to_dict()
    assert header.surface.friction == DEFAULT_WALL.friction
    assert validate(tmp_path) == {"dataset": [], "fast": []}


def test_valid_dataset_has_no_problem(dataset):
    before = digest(dataset)
    assert validate(dataset) == {"dataset": [], "fast": [], "slow": []}
    assert digest(dataset) == before


def test_writer_never_overwrites_a_different_dataset(dataset, logs):
    other = DatasetHeader(HEADER.tool, Surface(np.array([0.7, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])), 1e-3)
    with pytest.raises(DatasetError, match="another header"):
        DatasetWriter(dataset, other)
    writer = DatasetWriter(dataset, HEADER)
    before = digest(dataset)
    writer.add_trial(entry("fast", 0.15, logs[0.15]), logs[0.15])  # identical: no-op
    with pytest.raises(DatasetError, match="already exists"):
        writer.add_trial(entry("fast", 0.15, logs[0.1]), logs[0.1])
    with pytest.raises(DatasetError, match="already exists"):
        writer.add_trial(TrialEntry("new", "slow.csv", 0.1), logs[0.15])
    assert digest(dataset) == before


def corrupt_csv(path, edit):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda d: (d / "slow.csv").unlink(), "slow.csv does not exist"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: [ls[0].replace("tau3", "tau_3")] + ls[1:]),
         "lacks the column.*tau3"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: ls[:5] + [ls[5].replace(ls[5].split(",")[3], "nan", 1)] + ls[6:]),
         "NaN"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: ls[:5] + [ls[6], ls[5]] + ls[7:]), "time does not increase"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: ls[:20]), "fewer than the"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: ls[:2]), "holds 1 samples"),
        (lambda d: corrupt_csv(d / "slow.csv", lambda ls: ls[:120]), "no impact found"),
    ],
)
def test_validation_reports_broken_trials(dataset, damage, message):
    damage(dataset)
    before = digest(dataset)
    problems = validate(dataset)
    assert problems["fast"] == [] and problems["dataset"] == []
    assert len(problems["slow"]) == 1
    assert re.search(message, problems["slow"][0]), problems["slow"]
    assert digest(dataset) == before


def test_validation_reports_a_manifest_disagreeing_with_the_files(dataset):
    manifest = json.loads((dataset / "dataset.json").read_text())
    manifest["trials"][0]["impact_time"] += 0.05
    manifest["control_period"] = 0.002
    manifest["trials"][1]["force_file"] = "missing_force.csv"
    (dataset / "dataset.json").write_text(json.dumps(manifest))
    (dataset / "stray.csv").write_text("t\n0\n")
    problems = validate(dataset)
    assert any("stray.csv" in p for p in problems["dataset"])
    assert any("manifest says 0.002" in p for p in problems["fast"])
    assert any("impact_time" in p for p in problems["fast"])
    assert problems["slow"] == ["missing_force.csv does not exist"]


def test_validation_reports_a_broken_manifest(tmp_path):
    assert validate(tmp_path)["dataset"] == [f"the dataset manifest {tmp_path / 'dataset.json'} does not exist"]
    (tmp_path / "dataset.json").write_text(json.dumps({"format": "other/1"}))
    assert "lacks the key" in validate(tmp_path)["dataset"][0]
    with pytest.raises(DatasetError):
        read_dataset(tmp_path)


def _rewrite_manifest(directory, edit):
    path = directory / "dataset.json"
    manifest = json.loads(path.read_text())
    edit(manifest)
    path.write_text(json.dumps(manifest))


@pytest.mark.parametrize("robot", ["panda", "fr3"])
def test_a_first_version_manifest_reads_as_the_impact_tip(tmp_path, logs, robot):
    writer = DatasetWriter(tmp_path, DatasetHeader(TOOLS["impact_tip"], DEFAULT_WALL, 1e-3, robot=robot))
    writer.add_trial(TrialEntry("fast", "fast.csv", 0.15), logs[0.15])
    _rewrite_manifest(tmp_path, lambda m: m.__setitem__(
        "tool", {"frame": f"{robot}_hand", "contact_point": [0.0, 0.0, TOOL_TIP_OFFSET]}))
    header = read_dataset(tmp_path).header
    assert header.tool is TOOLS["impact_tip"] and header.robot == robot
    assert header.choice.same_as(header.choice.of(robot, "impact_tip"))
    _rewrite_manifest(tmp_path, lambda m: m["tool"].__setitem__("contact_point", [0.0, 0.0, 0.2]))
    with pytest.raises(DatasetError, match="is not the impact tool"):
        read_dataset(tmp_path)


@pytest.mark.parametrize("tool", ["franka_hand", "pad"])
def test_the_manifest_records_and_reads_back_the_full_tool(tmp_path, logs, tool):
    header = DatasetHeader(TOOLS[tool], DEFAULT_WALL, 1e-3, robot="fr3")
    DatasetWriter(tmp_path, header).add_trial(TrialEntry("fast", "fast.csv", 0.15), logs[0.15])
    read = read_dataset(tmp_path).header
    assert read.robot == "fr3" and read.tool.as_dict() == TOOLS[tool].as_dict()
    _rewrite_manifest(tmp_path, lambda m: m["tool"].__setitem__("mass", -1.0))
    with pytest.raises(DatasetError, match="tool: the tool mass"):
        read_dataset(tmp_path)
