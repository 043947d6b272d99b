"""``impactqp sweep``: --example is a runnable config; --simulate with --plant; bad input is one
line and exit code 2 before any work."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.scenarios.cli import main
from impactqp.scenarios.max_speed_search import APPROACH_LIMIT_FRACTION, approach_velocity_limit
from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.config import EXAMPLE
from impactqp.scenarios.trial import TrialRunner
from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import TrialSpec

from cli_checks import one_line_bad_input, run


def example_with(tmp_path, replacements=()) -> str:
    text = EXAMPLE
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    return str(path)


def test_the_example_config_runs_and_writes_one_row_per_cell(tmp_path, capsys):
    assert main(["sweep", "--example"]) == 0
    assert capsys.readouterr().out == EXAMPLE
    config = example_with(tmp_path, [("size = [0.4, 0.3]", "size = [0.1, 0.1]")])
    out = tmp_path / "out"
    assert main(["sweep", config, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cells"] == 4 and summary["cells_simulated"] == 0
    assert sum(pq.read_table(p).num_rows for p in out.glob("chunk-*.parquet")) == 4
    assert all((out / name).name.endswith(".png") and (out / name).exists() for name in summary["figures"])


def test_a_simulated_cell_is_the_highest_feasible_speed_on_the_plant_of_the_plant_file(tmp_path, capsys, robot):
    """One cell (the tip of elbow_up), 3 kg of payload. The row's simulated speed v is feasible on
    that plant and v + tolerance is not (the bisection's bracket), and v is violated on the
    nominal plant: the plant file reached the simulation."""
    tolerance = 0.1
    config = example_with(tmp_path, [
        ("origin = [0.6, -0.2, 0.5]", "origin = [0.6, 0.0, 0.7]"), ("size = [0.4, 0.3]", "size = [0.0, 0.0]"),
        ("tolerance = 0.005", f"tolerance = {tolerance}"),
    ])
    plant = PlantParameters(payload_mass=3.0)
    plant_file = tmp_path / "plant.json"
    plant.to_json(plant_file)
    out = tmp_path / "out"
    assert main(["sweep", config, "--out", str(out), "--simulate", "--plant", str(plant_file), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cells_simulated"] == 1
    (row,) = store.read_table(out).to_pylist()
    assert row["simulated_status"] == "simulated" and row["simulated_impacts"] >= 2
    assert 0.0 < row["qp_limited_speed"] and 0.0 < row["simulated_max_speed"]
    q = np.array([row[f"q{j}"] for j in range(1, 8)])
    point = np.array([row["point_x"], row["point_y"], row["point_z"]])
    normal = np.array([row["normal_x"], row["normal_y"], row["normal_z"]])
    surface = Surface(point, normal, DEFAULT_WALL.friction)
    speed = row["simulated_max_speed"]

    def violated(runner, v):
        spec = TrialSpec("cell", q, v, restitution=row["restitution"], impact_duration=row["impact_duration"])
        return runner.run(spec).violated

    heavy = TrialRunner.build(surface, plant)
    assert not violated(heavy, speed)
    if speed < APPROACH_LIMIT_FRACTION * approach_velocity_limit(robot, q, normal):
        assert violated(heavy, speed + tolerance)
    assert violated(TrialRunner.build(surface, None), speed)


BAD_CONFIGS = [
    ("[grid\n", "not valid TOML"),
    ("[grid]\nfoo = 1\n", "unknown key grid.foo"),
    ("", "needs a [grid] table"),
    (EXAMPLE.replace('normals = [[-1.0, 0.0, 0.0]]', "normals = []"), "empty"),
    (EXAMPLE.replace("spacing = 0.1", "spacing = 0.0"), "grid.spacing must be > 0"),
    (EXAMPLE.replace("spacing = 0.1", "spacing = -1"), "grid.spacing must be > 0"),
    (EXAMPLE.replace('jump_model = ["crb"]', 'jump_model = ["crb"]\ngain = 2'), "unknown key controller.gain"),
]


@pytest.mark.parametrize("text, message", BAD_CONFIGS)
def test_bad_config_is_one_line_and_exit_code_2_before_any_work(tmp_path, capsys, text, message):
    config = tmp_path / "bad.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main(["sweep", str(config), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--simulate", "--plant", "{tmp}/missing.json"], "does not exist"),
        (["--simulate", "--plant", "{tmp}"], "is a directory, not a file"),
        (["--simulate", "--plant", "{tmp}/unknown.json"], "unknown plant parameter"),
        (["--simulate", "--plant", "{tmp}/negative.json"], "payload_mass"),
        (["--simulate", "--plant", "{tmp}/broken.json"], "--plant"),
        (["--plant", "{tmp}/unknown.json"], "add --simulate"),
        (["--out", "{tmp}/unknown.json"], "not a directory"),
        (["--out", "{tmp}/unknown.json/sub"], "not a directory"),
    ],
)
def test_bad_plant_or_output_is_one_line_and_exit_code_2_before_any_work(tmp_path, capsys, args, message):
    config = example_with(tmp_path)
    (tmp_path / "unknown.json").write_text('{"stiffness": 1.0}')
    (tmp_path / "negative.json").write_text('{"payload_mass": -1.0}')
    (tmp_path / "broken.json").write_text('{"payload_mass": ')
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    before = sorted(p.name for p in tmp_path.iterdir())
    out = [] if "--out" in args else ["--out", str(tmp_path / "out")]
    assert main(["sweep", config, *out, *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_a_second_run_into_the_same_directory_needs_resume(tmp_path, capsys):
    config = example_with(tmp_path, [("size = [0.4, 0.3]", "size = [0.0, 0.0]")])
    out = str(tmp_path / "out")
    assert main(["sweep", config, "--out", out, "--json"]) == 0
    assert main(["sweep", config, "--out", out, "--json"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["sweep", config, "--out", out, "--resume", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["chunks_skipped"] == 1


def _truncate(path, other):
    path.write_bytes(path.read_bytes()[:3000])  # the rows' start, no footer


def _directory(path, other):
    path.unlink()
    path.mkdir()


def _foreign(path, other):
    path.write_bytes(other.read_bytes())  # the first chunk of a sweep of another restitution


@pytest.mark.parametrize("spoil, message", [
    (_truncate, "is not a Parquet file; remove it and --resume to write it again"),
    (_directory, "is a directory, not a file"),
    (_foreign, "holds the rows of another sweep (its config, --simulate or --plant); remove it and --resume"),
])
def test_resuming_over_a_spoilt_chunk_is_one_line_naming_it(tmp_path, capsys, spoil, message):
    """A chunk on disk that is not a whole Parquet file of this sweep: one line of bad input naming
    it and what is wrong, before any cell; the directory is left as it was."""
    config = example_with(tmp_path, [("size = [0.4, 0.3]", "size = [0.1, 0.1]")])
    (tmp_path / "other").mkdir()
    other = example_with(tmp_path / "other",
                         [("size = [0.4, 0.3]", "size = [0.1, 0.1]"), ("restitution = [0.0]", "restitution = [0.1]")])
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    assert main(["sweep", config, "--out", str(out), "--json"]) == 0
    assert main(["sweep", other, "--out", str(elsewhere), "--json"]) == 0
    capsys.readouterr()
    chunk = store.chunk_path(out, 0)
    spoil(chunk, store.chunk_path(elsewhere, 0))
    before = {p.name: p.read_bytes() if p.is_file() else None for p in out.iterdir()}
    code, stdout, err = run(capsys, "sweep", config, "--out", str(out), "--resume", "--json")
    one_line_bad_input(code, stdout, err, f"the sweep chunk {chunk} {message}")
    assert {p.name: p.read_bytes() if p.is_file() else None for p in out.iterdir()} == before


def test_resuming_over_a_fifo_chunk_is_one_line_naming_it(tmp_path, capsys):
    """A FIFO is never opened (a read would wait for a writer): the command runs in its own
    interpreter, so that a regression fails at the guard instead of hanging the suite."""
    import os
    import subprocess
    import sys

    config = example_with(tmp_path, [("size = [0.4, 0.3]", "size = [0.1, 0.1]")])
    out = tmp_path / "out"
    assert main(["sweep", config, "--out", str(out), "--json"]) == 0
    chunk = store.chunk_path(out, 0)
    chunk.unlink()
    os.mkfifo(chunk)
    done = subprocess.run([sys.executable, "-m", "impactqp", "sweep", config, "--out", str(out), "--resume"],
                          capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    one_line_bad_input(done.returncode, done.stdout, done.stderr,
                       f"the sweep chunk {chunk} is not a regular file (a FIFO, a socket or a device)")
