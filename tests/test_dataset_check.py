"""Dataset checks: a read-only validation that names every broken trial, file and manifest key."""

import json
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from impactqp.controller.measured.dataset import DatasetError, read_dataset
from impactqp.controller.measured.dataset_check import validate

from conftest import g1_model, file_digests, g1_dataset, write_dataset


def test_valid_dataset_has_no_problem(dataset):
    before = file_digests(dataset)
    assert validate(dataset) == {"dataset": [], "fast": [], "slow": []}
    assert file_digests(dataset) == before


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
    before = file_digests(dataset)
    problems = validate(dataset)
    assert problems["fast"] == [] and problems["dataset"] == []
    assert len(problems["slow"]) == 1
    assert re.search(message, problems["slow"][0]), problems["slow"]
    assert file_digests(dataset) == before


@pytest.mark.parametrize("steps, message", [
    ([0.004] * 6, r"encoder_step must be a list of 7 numbers"),
    ([0.004] * 6 + [-0.001], r"encoder_step must be 7 steps of dq in \[0, 0.1\] rad/s"),
    ([0.004] * 6 + [0.5], r"encoder_step must be 7 steps"),
    ("0.004", r"encoder_step must be a list"),
])
def test_a_bad_encoder_step_is_a_problem_of_the_manifest(dataset, steps, message):
    """The manifest's optional encoder_step: one step per joint, each in [0, 0.1] rad/s; anything
    else is named (before: the key was ignored, 0 problems)."""
    manifest = json.loads((dataset / "dataset.json").read_text())
    manifest["encoder_step"] = [0.004] * 7
    (dataset / "dataset.json").write_text(json.dumps(manifest))
    assert validate(dataset) == {"dataset": [], "fast": [], "slow": []}
    manifest["encoder_step"] = steps
    (dataset / "dataset.json").write_text(json.dumps(manifest))
    problems = validate(dataset)["dataset"]
    assert len(problems) == 1 and re.search(message, problems[0]), problems


def test_a_trial_file_that_is_a_symbolic_link_loop_is_reported(dataset):
    (dataset / "slow.csv").unlink()
    (dataset / "slow.csv").symlink_to(dataset / "slow.csv")
    problems = validate(dataset)
    assert problems["fast"] == [] and problems["dataset"] == []
    assert len(problems["slow"]) == 1 and "symbolic-link loop" in problems["slow"][0], problems["slow"]


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


def _set_cell(path, row, column, value):
    lines = [line.split(",") for line in path.read_text().splitlines()]
    lines[row][lines[0].index(column)] = value
    path.write_text("\n".join(",".join(x) for x in lines) + "\n")


def test_a_g1_dataset_is_valid_and_its_impact_found(tmp_path):
    g1_dataset(tmp_path)
    before = file_digests(tmp_path)
    assert validate(tmp_path) == {"dataset": [], "g": []}
    assert file_digests(tmp_path) == before


@pytest.mark.parametrize("column, value, message", [
    ("q5", "100", r"q5 = 100.0000 rad at data row 7 lies outside the joint limits"),
    ("base_qw", "7", r"base quaternion's norm is .* at data row 7, not 1"),
    ("t", "0.5", r"time does not increase at data row 8"),
    (f"tau{g1_model().n_joints}", "inf", r"NaN or infinite value \(data row 7\)"),  # the last joint's
])
def test_a_g1_trial_out_of_what_the_robot_logs_is_named(tmp_path, column, value, message):
    g1_dataset(tmp_path)
    _set_cell(tmp_path / "g.csv", 7, column, value)
    problems = validate(tmp_path)
    assert problems["dataset"] == [] and len(problems["g"]) == 1
    assert re.search(message, problems["g"][0]), problems["g"]


def rewrite_times(path, edit):
    """Rewrite the time column of a trial CSV with ``edit(t)`` (the other columns kept)."""
    lines = path.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    t = edit(np.array([float(r[0]) for r in rows]))
    path.write_text("\n".join([lines[0]] + [",".join([repr(float(x))] + r[1:]) for x, r in zip(t, rows)]) + "\n")


@pytest.mark.parametrize("dropped", [[40], [40, 41, 90]])
def test_dropped_samples_are_named_with_where_they_are(dataset, dropped):
    # the time stamps say samples are missing: the steps after them are 2 or 3 periods long
    lines = (dataset / "slow.csv").read_text().splitlines()
    (dataset / "slow.csv").write_text("\n".join(line for k, line in enumerate(lines) if k - 1 not in dropped) + "\n")
    problems = validate(dataset)
    assert problems["fast"] == [] and problems["dataset"] == []
    gaps = len({k - i for i, k in enumerate(dropped)})  # runs of consecutive dropped rows
    (message,) = [p for p in problems["slow"] if "missing" in p]
    assert f"{len(dropped)} sample(s) missing in {gaps} gap(s)" in message
    assert f"data row {dropped[0]}:" in message and "sampled every" not in " ".join(problems["slow"])


@given(amplitude=st.floats(0.1, 0.24), seed=st.integers(0, 2**16))
@settings(max_examples=10, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_jittered_time_stamps_are_jitter_not_a_wrong_rate(dataset_logs, tmp_path_factory, amplitude, seed):
    # each stamp moved by up to +-amplitude periods (a step stays under 1.5 periods: no gap): the rate is
    # right, the stamps wander
    directory = write_dataset(tmp_path_factory.mktemp("jitter"), dataset_logs)
    rng = np.random.default_rng(seed)
    rewrite_times(directory / "slow.csv", lambda t: t + 0.001 * amplitude * np.sign(rng.uniform(-1, 1, t.shape)) * rng.uniform(0.7, 1, t.shape))
    problems = validate(directory)["slow"]
    assert any("jitter" in p for p in problems), problems
    assert not any("sampled every" in p or "missing" in p for p in problems), problems


def test_one_late_stamp_is_jitter_named_with_its_row(dataset):
    """Data row 50's stamp 0.3 periods late: the step into it is 1.3 periods, the step out 0.7;
    both are jitter, the first after data row 49, the larger (equal: the first) there too."""
    rewrite_times(dataset / "slow.csv", lambda t: t + 0.0003 * (np.arange(len(t)) == 49))
    problems = validate(dataset)["slow"]
    (message,) = problems
    assert "jitter: 2 of " in message and "the first after data row 49 (t = 0.0480 s)" in message, message
    assert "the largest (0.0003 s) after data row 49" in message, message


def test_a_uniformly_wrong_rate_is_named_as_such(dataset):
    rewrite_times(dataset / "slow.csv", lambda t: 1.05 * t)
    problems = validate(dataset)["slow"]
    assert any("sampled every 0.00105 s" in p for p in problems) and not any("jitter" in p for p in problems), problems
