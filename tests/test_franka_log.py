"""libfranka logToCSV files imported as a dataset (controller/measured/franka_log.py).

The logs are written here from simulated trials in libfranka's own format, as ``src/log.cpp``
writes them: header names ``name[i]`` separated by ", " inside an array (older libfranka) or ","
(newer), values with the ostream default of 6 significant digits, time in ms, and each row
holding the state of cycle n+1 (its joint torques those of period n) with the command of cycle n.
"""

import hashlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.franka_log import import_franka_logs, logged_period, read_franka_csv
from impactqp.controller.measured.impact import measure_impact
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.causes import ArmatureCause, per_group
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset
from impactqp.sim.plant import PlantParameters

ARMATURE = (0.5, 0.15)

ARRAYS = [
    ("state.q", JOINTS), ("state.q_d", JOINTS), ("state.dq", JOINTS), ("state.dq_d", JOINTS), ("state.tau_J", JOINTS),
    ("state.tau_ext_hat_filtered", JOINTS), ("cmd.q_d", JOINTS), ("cmd.dq_d", JOINTS), ("cmd.O_T_EE_d", 16),
    ("cmd.O_dP_EE_d", 6), ("cmd.tau_J_d", JOINTS),
]


def libfranka_header(separator: str) -> str:
    """csvRobotStateHeader() + "," + csvRobotCommandHeader() of libfranka's src/log.cpp, with the
    name separator of the libfranka version."""
    names = lambda name, size: separator.join(f"{name}[{i}]" for i in range(size))  # noqa: E731
    return f"time{separator}success_rate{separator}" + ",".join(names(n, s) for n, s in ARRAYS)


def libfranka_csv(log: TrialLog, separator: str) -> str:
    n = len(log)
    command = np.vstack([np.zeros((1, JOINTS)), log.dq_cmd[:-1]])  # row k: state k with the command of k - 1
    # the state of cycle k measures the torque applied over period k - 1 (the dataset's tau[k - 1])
    measured_torque = np.vstack([log.tau[:1], log.tau[:-1]])
    pose = np.tile(np.eye(4).T.ravel(), (n, 1))
    table = np.column_stack([
        np.round(log.t * 1000.0), np.ones(n), log.q, log.q, log.dq, log.dq, measured_torque, np.zeros((n, JOINTS)),
        log.q, command, pose, np.zeros((n, 6)), log.tau,
    ])
    rows = [",".join(f"{x:.6g}" for x in row) for row in table]
    return "\n".join([libfranka_header(separator), *rows]) + "\n"


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """Two simulated trials of a plant with armature (no force sensor is read by the import) and
    their libfranka logs."""
    directory = tmp_path_factory.mktemp("source")
    plant = PlantParameters(armature=per_group(ARMATURE, JOINTS))
    generate_dataset(directory, DatasetRequest(plant=plant, postures=["elbow_up", "elbow_left"], speeds=[0.12], seed=5))
    dataset = read_dataset(directory)
    logs = {}
    for separator, tag in ((", ", "old"), (",", "new")):
        for trial in dataset.trials:
            path = directory / f"franka_{tag}_{trial.entry.id}.log"
            path.write_text(libfranka_csv(trial.log, separator))
            logs[tag, trial.entry.id] = path
    return dataset, logs


def digest(paths) -> list[str]:
    return [hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths]


@pytest.mark.parametrize("tag", ["old", "new"])
def test_import_gives_back_the_trials_it_came_from(source, tmp_path, tag):
    dataset, logs = source
    paths = [logs[tag, t.entry.id] for t in dataset.trials]
    before = digest(paths)
    entries = import_franka_logs(tmp_path / "imported", paths, DEFAULT_WALL)
    assert digest(paths) == before
    assert all(not problems for problems in validate(tmp_path / "imported").values())
    imported = read_dataset(tmp_path / "imported")
    for trial, entry, original in zip(imported.trials, entries, dataset.trials):
        log, source_log = trial.log, original.log
        n = len(log)
        assert n == len(source_log) - 1  # the last row's command is not logged
        np.testing.assert_allclose(log.t, source_log.t[:n] - source_log.t[0], atol=1e-9)
        for name in ("q", "dq", "tau", "dq_cmd"):
            np.testing.assert_allclose(getattr(log, name), getattr(source_log, name)[:n], rtol=1e-5, atol=1e-6)
        # the estimated reference speed is the commanded approach speed
        assert entry.reference_normal_speed == pytest.approx(original.entry.reference_normal_speed, abs=2e-3)
        assert np.linalg.norm(entry.reference_tangential_velocity) <= 2e-3
        assert entry.posture == original.entry.posture
        # the impact measured on the import is the one the robot's own torques show in the source
        expected = measure_impact(source_log, use_force=False)
        np.testing.assert_allclose(measure_impact(log).dq_jump, expected.dq_jump, atol=1e-5)


def test_imported_logs_diagnose_like_the_dataset_they_came_from(source, tmp_path):
    """Same cause, same fitted armature per group (the import has no force log, so no impulse
    residuals: the fits agree to a few per cent, not exactly)."""
    dataset, logs = source
    import_franka_logs(tmp_path, [logs["old", t.entry.id] for t in dataset.trials], DEFAULT_WALL)
    imported = diagnose(tmp_path, causes=[ArmatureCause(JOINTS)]).summary()
    original = diagnose(dataset.directory, causes=[ArmatureCause(JOINTS)]).summary()
    assert imported["causes"] == original["causes"] == ["armature"]
    fitted = ArmatureCause(JOINTS).theta_of(imported["parameters"])
    np.testing.assert_allclose(fitted, ArmatureCause(JOINTS).theta_of(original["parameters"]), rtol=0.1)
    np.testing.assert_allclose(fitted, ARMATURE, rtol=0.2)
    assert imported["baseline_error"] == pytest.approx(original["baseline_error"], rel=0.1)


def test_the_manifest_holds_the_logged_period_and_no_invented_friction(source, tmp_path):
    """A 1 ms clock is written as 0.001 s, and a robot log does not know the surface's friction."""
    import json

    dataset, logs = source
    import_franka_logs(tmp_path, [logs["new", t.entry.id] for t in dataset.trials], DEFAULT_WALL)
    text = (tmp_path / "dataset.json").read_text()
    manifest = json.loads(text)
    assert manifest["control_period"] == 0.001 and '"control_period": 0.001,' in text
    assert "friction" not in manifest["surface"]
    assert read_dataset(tmp_path).header.friction_known is False


@given(
    st.sampled_from([1.0, 0.5, 0.25, 2.0, 4.0, 0.1]),
    st.integers(min_value=0, max_value=10**9),
    st.integers(min_value=10, max_value=400),
)
def test_the_logged_period_is_the_clock_step_without_rounding_error(step_ms, start_ms, samples):
    time = start_ms + step_ms * np.arange(samples)
    period = logged_period(time)
    assert period == float(f"{step_ms / 1000.0:.6g}")
    assert len(repr(period)) <= 8  # e.g. 0.00025, never 0.0010000000000000009


def test_given_reference_speed_is_used_as_is(source, tmp_path):
    dataset, logs = source
    entries = import_franka_logs(tmp_path, [logs["new", dataset.trials[0].entry.id]], DEFAULT_WALL,
                                 reference_speed=0.2)
    assert entries[0].reference_normal_speed == 0.2


@pytest.mark.parametrize("speed", [1e308, 3.5, 0.0, -0.1, float("nan")])
def test_a_reference_speed_the_dataset_would_refuse_is_refused_before_writing(source, tmp_path, speed):
    """The import writes only what `dataset validate` accepts: an approach speed in (0, 3] m/s."""
    dataset, logs = source
    with pytest.raises(BadInputError, match="--reference-speed"):
        import_franka_logs(tmp_path / "out", [logs["new", dataset.trials[0].entry.id]], DEFAULT_WALL,
                           reference_speed=speed)
    assert not (tmp_path / "out").exists()


def test_old_and_new_header_separators_read_the_same_columns(source):
    dataset, logs = source
    trial_id = dataset.trials[0].entry.id
    old, new = read_franka_csv(logs["old", trial_id], JOINTS), read_franka_csv(logs["new", trial_id], JOINTS)
    assert old.keys() == new.keys() and len(old) == 1 + len(ARRAYS)
    for key in old:
        np.testing.assert_array_equal(old[key], new[key])


@settings(max_examples=25, deadline=None)
@given(cut=st.integers(min_value=1, max_value=300), tag=st.sampled_from(["old", "new"]))
def test_truncated_logs_are_refused_with_one_line(source, tmp_path_factory, cut, tag):
    dataset, logs = source
    text = logs[tag, dataset.trials[0].entry.id].read_text()
    path = tmp_path_factory.mktemp("cut") / "cut.csv"
    path.write_text(text[: len(text) - cut])  # a write cut short, mid-line
    with pytest.raises(BadInputError) as error:
        import_franka_logs(path.parent / "out", [path], DEFAULT_WALL)
    message = str(error.value)
    assert "\n" not in message and str(path) in message
    assert not (path.parent / "out" / "dataset.json").exists()


@pytest.mark.parametrize(
    "text, words",
    [
        ("", "empty"),
        ("t,q1,q2\n0,0,0\n", "not a libfranka"),
        ("time, success_rate, state.q[0], state.q[1]\n0,1,0,0\n", "lacks the column"),
        ("\x89PNG\r\n\x1a\n", "not a libfranka"),
    ],
)
def test_foreign_files_are_refused_with_one_line(tmp_path, text, words):
    path = tmp_path / "foreign.csv"
    path.write_text(text)
    with pytest.raises(BadInputError) as error:
        import_franka_logs(tmp_path / "out", [path], DEFAULT_WALL)
    assert words in str(error.value) and "\n" not in str(error.value)


def test_a_bad_log_among_good_ones_writes_nothing(source, tmp_path):
    dataset, logs = source
    bad = tmp_path / "bad.csv"
    bad.write_text(libfranka_header(",") + "\n" + "1,2,3\n")
    with pytest.raises(BadInputError, match="bad.csv"):
        import_franka_logs(tmp_path / "out", [logs["new", dataset.trials[0].entry.id], bad], DEFAULT_WALL)
    assert not (tmp_path / "out").exists()
