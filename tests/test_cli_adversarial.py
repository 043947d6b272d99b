"""Adversarial input for every command: exit code, one line naming the problem, input bytes intact.

Each row is (command line, expected exit code, fragment of the message). ``{data}`` stands for a
valid small dataset, ``{bad}`` for a dataset directory that the row's ``mutate`` breaks, and
``{tmp}`` for an empty scratch directory. Exit code 2 is bad input (one line on stderr), 1 a
validation report (``dataset validate``) that lists the problem on stdout.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from conftest import JOINTS
from impactqp.scenarios.cli import main
from impactqp.scenarios.sweep.config import EXAMPLE as SWEEP_EXAMPLE


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("adversarial") / "data"
    assert main(["dataset", "generate", str(out), "--postures", "elbow_up", "--speeds", "0.1,0.15", "--json"]) == 0
    return out


def snapshot(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def manifest_edit(edit):
    def mutate(directory: Path) -> None:
        path = directory / "dataset.json"
        manifest = json.loads(path.read_text())
        edit(manifest)
        path.write_text(json.dumps(manifest))

    return mutate


def set_trial(key, value, index=0):
    return manifest_edit(lambda m: m["trials"][index].__setitem__(key, value))


def write(name: str, text: str | bytes):
    def mutate(directory: Path) -> None:
        path = directory / name
        path.write_bytes(text if isinstance(text, bytes) else text.encode())

    return mutate


def shift_joint(row_value: float):
    def mutate(directory: Path) -> None:
        path = directory / "t0000.csv"
        lines = path.read_text().splitlines()
        cells = lines[5].split(",")
        cells[1] = str(row_value)  # q1 of the fifth sample
        lines[5] = ",".join(cells)
        path.write_text("\n".join(lines) + "\n")

    return mutate


def header_only(name: str):
    def mutate(directory: Path) -> None:
        path = directory / name
        path.write_text(path.read_text().splitlines()[0] + "\n")

    return mutate


def replace_by_directory(name: str):
    def mutate(directory: Path) -> None:
        (directory / name).unlink()
        (directory / name).mkdir()

    return mutate


def replace_by_directory_new(name: str):
    def mutate(directory: Path) -> None:
        (directory / name).mkdir()

    return mutate


def make_fifo(name: str):
    def mutate(directory: Path) -> None:
        os.mkfifo(directory / name)

    return mutate


def nested_manifest(directory: Path) -> None:
    (directory / "dataset.json").write_text("[" * 100_000 + "]" * 100_000)


ROWS = [
    # predict
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "1e308", "--json"], None, 2, "m/s"),
    (["predict", "--q", "0,0,0", "--normal", "-1,0,0", "--speed", "0.1"], None, 2, f"{JOINTS} values"),
    (["predict", "--posture", "elbow_up", "--normal", "0,0,0", "--speed", "0.1"], None, 2, "non-zero"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1", "--tangential", "0.1,0,0"],
     None, 2, "orthogonal"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1", "--restitution", "nan"],
     None, 2, "[0, 1]"),
    # numbers near the end of the float range: no overflow warning, the message shows the number given
    (["predict", "--normal", "-1,0,0", "--speed", "0.15", "--q", "1e308,0,0,-2,0,2,0"], None, 2, "q1 = 1e+308"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.15", "--tangential", "0,1e308,0"],
     None, 2, "got 1e+308 m/s"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.15", "--tangential", "0,1.7e308,1.7e308"],
     None, 2, "got 1.7e+308 m/s"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.15", "--friction", "-0.2"], None, 2,
     "the friction coefficient --friction must lie in [0, 10]"),
    (["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.15", "--friction", "0.3", "--method",
      "classical_normal"], None, 2, "classical_normal has no frictional form"),
    (["predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0", "--speed", "0.15", "--friction", "-0.3"],
     None, 2, "the friction coefficient --friction must lie in [0, 10]"),
    (["predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0", "--speed", "0.15", "--friction", "0.3",
      "--method", "classical_normal"], None, 2, "classical_normal model has no held-contact form"),
    # postures: no input but its options
    (["postures", "--bogus"], None, 2, "No such option"),
    # simulate
    (["simulate", "--posture", "elbow_up", "--speed", "1e9"], None, 2, "[0.001, 3] m/s"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{tmp}"], None, 2, "is a directory, not a file"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "identified_pnda"], None, 2,
     "no built-in plant 'identified_pnda'; built-in: identified_panda"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--out", "{data}/t0000.csv"], None, 2,
     "not a directory"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--video", "{data}/t0000.csv/x.gif"], None, 2,
     "not a directory"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{bad}/p.json"],
     write("p.json", '{"payload_mass": 1e6}'), 2, "payload_mass must lie in [0, 5] kg, got 1000000.0"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--plant", "{bad}/p.json"],
     write("p.json", '{"payload_mass": true}'), 2, "payload_mass must be a number"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1e10,0,0"], None, 2,
     "must lie within 10 m of the robot's base"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--wall-point", "1e308,1e308,0"], None, 2,
     "must lie within 10 m of the robot's base"),
    # campaign
    (["campaign", "--speeds", "50"], None, 2, "[0.001, 3] m/s"),
    (["campaign", "--out", "{data}/dataset.json", "--speeds", "0.1"], None, 2, "not a directory"),
    (["campaign", "--postures", "nowhere"], None, 2, "unknown posture"),
    # max-speed
    (["max-speed", "--posture", "elbow_up", "--impact-duration", "1e-9"], None, 2, "one control period"),
    (["max-speed", "--posture", "elbow_up", "--plant", "{tmp}"], None, 2, "is a directory, not a file"),
    (["max-speed", "--posture", "elbow_up", "--wall-normal", "nan,0,0"], None, 2, "non-finite"),
    (["max-speed", "--posture", "elbow_up", "--tolerance", "1e-300"], None, 2,
     "the bisection tolerance must lie in [0.0001, 0.5] m/s"),
    # dataset validate: a report with exit code 1 that names the problem
    (["dataset", "validate", "{bad}"], set_trial("file", "../../../../etc/passwd"), 1, "inside the dataset"),
    (["dataset", "validate", "{bad}"], set_trial("reference_normal_speed", float("nan")), 1, "reference_normal_speed"),
    (["dataset", "validate", "{bad}"], set_trial("reference_normal_speed", -0.1), 1, "reference_normal_speed"),
    (["dataset", "validate", "{bad}"], set_trial("reference_normal_speed", "soon"), 1,
     "trial 't0000': reference_normal_speed must be a number"),
    (["dataset", "validate", "{bad}"], set_trial("force_file", 5), 1, "force_file must be a non-empty string"),
    (["dataset", "validate", "{bad}"], set_trial("posture", ["elbow_up"]), 1, "posture must be a non-empty string"),
    (["dataset", "validate", "{bad}"], set_trial("id", "dataset"), 1, "reserved"),
    (["dataset", "validate", "{bad}"], shift_joint(5.0), 1, "outside the joint limits"),
    (["dataset", "validate", "{bad}"], replace_by_directory("t0000.csv"), 1, "is a directory"),
    (["dataset", "validate", "{bad}"], write("t0000.csv", "root:x:0:0:root:/root:/bin/bash\n"), 1,
     "lacks the column"),
    (["dataset", "validate", "{bad}"], header_only("t0000.csv"), 1, "holds no samples"),
    (["dataset", "validate", "{bad}"], manifest_edit(lambda m: m.__setitem__("robot", "kuka")), 1,
     "robots we model"),
    (["dataset", "validate", "{bad}"], nested_manifest, 1, "nested too deeply"),
    (["dataset", "validate", "{data}/t0000.csv"], None, 2, "is a file"),
    # dataset generate
    (["dataset", "generate", "{tmp}/out", "--speeds", "50"], None, 2, "[0.001, 3] m/s"),
    (["dataset", "generate", "{data}/t0000.csv", "--speeds", "0.1"], None, 2, "is a file"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--repeats", "1000000"], None, 2,
     "repeats must be a whole number in [1, 100]"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--noise-dq", "1e9"], None, 2, "--noise-dq"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--jobs", "1000000"], None, 2, "--jobs must lie in"),
    (["dataset", "generate", "{tmp}/out", "--postures", "elbow_up", "--speeds", "0.1", "--jobs", "1", "--seed", "-1"],
     None, 2, "the seed --seed must be a whole number >= 0, got -1"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--repeats", "-1"], None, 2,
     "repeats must be a whole number in [1, 100]"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--seed", "0.5"], None, 2, "'0.5' is not a valid integer"),
    (["dataset", "generate", "{tmp}/out", "--speeds", "0.1", "--jobs", "-1"], None, 2, "--jobs must lie in"),
    (["dataset", "generate", "{tmp}/out", "--plant", "{data}"], None, 2, "is a directory"),
    # diagnose
    (["diagnose", "{bad}"], manifest_edit(lambda m: m.__setitem__("robot", "kuka")), 2, "robots we model"),
    (["diagnose", "{bad}"], manifest_edit(lambda m: m["tool"].__setitem__("contact_point", [0.0, 0.0, 0.2])), 2,
     "must lie on the contact surface"),
    (["diagnose", "{bad}"], manifest_edit(lambda m: m["tool"].__setitem__("frame", "panda_link7")), 2,
     "choose from hand, flange"),
    (["diagnose", "{bad}"], manifest_edit(lambda m: m.__setitem__(
        "tool", {"frame": "panda_hand", "contact_point": [0.0, 0.0, 0.2]})), 2, "is not the impact tool"),
    (["run", "--backend", "replay", "--dataset", "{bad}", "--log", "{tmp}/log"],
     manifest_edit(lambda m: m["tool"].__setitem__("contact_point", [0.0, 0.0, 0.2])), 2,
     "must lie on the contact surface"),
    (["run", "--backend", "replay", "--dataset", "{bad}", "--log", "{tmp}/log"], shift_joint(5.0), 2,
     "t0000.csv: q1 = 5.0000 rad at data row"),
    (["run", "--backend", "replay", "--dataset", "{bad}", "--log", "{tmp}/log", "--robot", "fr3"], None, 2,
     "differ from --robot/--tool (fr3, impact_tip)"),
    (["diagnose", "{data}", "--save-plant", "{tmp}"], None, 2, "is a directory"),
    (["diagnose", "{data}", "--report", "{data}/dataset.json"], None, 2, "is a file"),
    (["diagnose", "{data}", "--jobs", "0"], None, 2, "--jobs"),
    # run: a controller configuration is read and checked before the robot moves
    (["run", "--config", "{bad}/c.toml", "--log", "{tmp}/log"], write("c.toml", "dt = nan\n"), 2,
     "dt must lie in [0.0001, 0.01] s"),
    (["run", "--config", "{bad}/c.toml", "--log", "{tmp}/log"], write("c.toml", 'dt = "fast"\n'), 2,
     "dt must be a number"),
    (["run", "--config", "{bad}/c.toml", "--log", "{tmp}/log"], write("c.toml", "[limits]\njerk_scale = 1e-300\n"),
     2, "limits.jerk_scale"),
    (["run", "--config", "{bad}/c.yaml", "--log", "{tmp}/log"], write("c.yaml", "dt: [1\n"), 2, "not valid YAML"),
    (["run", "--config", "{bad}/c.yaml", "--log", "{tmp}/log"], write("c.yaml", b"\xff\xfe\x00"), 2, "not a UTF-8"),
    (["run", "--config", "{bad}/c.yaml", "--log", "{tmp}/log"],
     write("c.yaml", "x: " + "[" * 100_000 + "]" * 100_000), 2, "nested too deeply"),
    (["run", "--config", "{tmp}", "--log", "{tmp}/log"], None, 2, "unsupported configuration file"),
    (["oblique", "--qp-speed", "--jump-model", "", "--out", "{tmp}/o"], None, 2, "jump model"),
    (["run", "--config", "{bad}/c.toml", "--log", "{tmp}/log"], replace_by_directory_new("c.toml"), 2,
     "is a directory"),
    (["run", "--speed", "1e9", "--log", "{tmp}/log"], None, 2, "(0, 3] m/s"),
    (["run", "--duration", "1e9", "--log", "{tmp}/log"], None, 2, "--duration must lie in (0, 60] s"),
    (["run", "--log", "{data}/t0000.csv"], None, 2, "--log"),
    (["run", "--backend", "replay", "--dataset", "{data}", "--plant", "identified_panda", "--log", "{tmp}/log"], None,
     2, "--plant applies to --backend sim only, not replay"),
    (["run", "--dataset", "{data}", "--log", "{tmp}/log"], None, 2, "--dataset applies to --backend replay only, not sim"),
    # sweep and import-franka: the output directory is checked before any work
    (["sweep", "{bad}/c.toml", "--out", "{tmp}/s"], write("c.toml", b"\xff\xfe"), 2, "not a UTF-8 text file"),
    (["sweep", "{bad}/c.toml", "--out", "{tmp}/s", "--jobs", "1000000"], write("c.toml", SWEEP_EXAMPLE), 2,
     "--jobs must lie in"),
    (["sweep", "{bad}/c.toml", "--out", "{tmp}/s", "--jobs", "0"], write("c.toml", SWEEP_EXAMPLE), 2,
     "--jobs must lie in"),
    (["demo", "--out", "{tmp}/demo", "--jobs", "0"], None, 2, "--jobs must lie in"),
    (["campaign", "--out", "{tmp}/c", "--jobs", "0"], None, 2, "--jobs must lie in"),
    (["max-speed", "--posture", "elbow_up", "--jobs", "-3"], None, 2, "--jobs must lie in"),
    (["sweep", "{bad}/c.toml", "--out", "{tmp}/s"], write("c.toml", "x = " + "[" * 100_000 + "]" * 100_000), 2,
     "nested too deeply"),
    (["sweep", "{bad}/c.toml", "--out", "{data}/dataset.json"], write("c.toml", SWEEP_EXAMPLE), 2,
     "--out: {data}/dataset.json exists and is not a directory"),
    (["sweep", "{bad}/c.toml", "--out", "{data}/dataset.json/x"], write("c.toml", SWEEP_EXAMPLE), 2,
     "which is not a directory"),
    (["dataset", "import-franka", "{data}/t0000.csv/x", "{data}/t0000.csv", "--surface-point", "0.6,0,0",
      "--surface-normal", "-1,0,0"], None, 2, "which is not a directory"),
    # demo
    (["demo", "--out", "{data}/dataset.json"], None, 2, "not a directory"),
    # an output path that is empty (the working directory) or a special file (which a write would replace)
    (["sweep", "{bad}/c.toml", "--out", ""], write("c.toml", SWEEP_EXAMPLE), 2, "--out is empty"),
    (["run", "--log", ""], None, 2, "--log is empty"),
    (["diagnose", "{data}", "--report", ""], None, 2, "--report is empty"),
    (["diagnose", "{data}", "--save-plant", ""], None, 2, "--save-plant is empty"),
    (["diagnose", "{data}", "--save-plant", "{bad}/plant.json"], make_fifo("plant.json"), 2, "is a special file"),
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--figure", "{bad}/f.png"], make_fifo("f.png"), 2,
     "is a special file"),
    (["max-speed", "--posture", "elbow_up", "--figure", "{bad}/f.png"], make_fifo("f.png"), 2, "is a special file"),
    # max-speed --friction is a closed form: options of the simulated search do not apply to it
    (["max-speed", "--posture", "elbow_up", "--friction", "0.3", "--tolerance", "0.05"], None, 2,
     "--tolerance does not apply to --friction"),
    (["max-speed", "--posture", "elbow_up", "--friction", "nan", "--tolerance", "0.05"], None, 2,
     "--friction: the friction of the impact rows must lie in [0, 2], got nan"),
    # a simulated approach slower than a trial can take, repeated or out-of-range conditions
    (["simulate", "--posture", "elbow_up", "--speed", "0.1", "--out", "{bad}"], replace_by_directory("t0000.csv"), 2,
     "t0000.csv is a directory, not a file"),
    (["simulate", "--posture", "elbow_up", "--speed", "1e-5"], None, 2, "[0.001, 3] m/s"),
    (["simulate", "--posture", "elbow_up", "--speed", "1e-300"], None, 2, "[0.001, 3] m/s"),
    (["campaign", "--postures", "elbow_up,elbow_up", "--speeds", "0.1", "--out", "{tmp}/c"], None, 2,
     "the postures repeat elbow_up"),
    (["campaign", "--postures", "elbow_up", "--speeds", "0.1", "--tangential", "0.05,0.05", "--out", "{tmp}/c"], None,
     2, "--tangential repeats 0.05"),
    (["dataset", "generate", "{tmp}/out", "--postures", "elbow_up,elbow_up", "--speeds", "0.1"], None, 2,
     "the postures repeat elbow_up"),
    (["dataset", "generate", "{tmp}/out", "--postures", "elbow_up", "--speeds", "0.1", "--tangential", "-5"], None, 2,
     "every tangential speed must lie in [-3, 3] m/s"),
]


@pytest.mark.filterwarnings("error")  # a warning would print more than the one line
@pytest.mark.parametrize("args, mutate, code, fragment", ROWS, ids=[" ".join(r[0][:3]) for r in ROWS])
def test_adversarial_input(dataset, tmp_path, capsys, args, mutate, code, fragment):
    bad = tmp_path / "bad"
    shutil.copytree(dataset, bad)
    if mutate is not None:
        mutate(bad)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    before, before_bad = snapshot(dataset), snapshot(bad)
    argv = [a.format(data=dataset, bad=bad, tmp=scratch) for a in args]
    fragment = fragment.format(data=dataset)
    assert main(argv) == code
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if code == 2:
        assert len(err.strip().splitlines()) == 1, err
        assert fragment in err, err
    else:
        assert fragment in out, out
        assert "root:x" not in out + err  # foreign content is never echoed
    assert snapshot(dataset) == before and snapshot(bad) == before_bad
    assert not list(scratch.rglob(".*.tmp")) and not list(dataset.rglob(".*"))


def test_written_files_follow_the_umask(tmp_path):
    previous = os.umask(0o027)
    try:
        assert main(["dataset", "generate", str(tmp_path / "d"), "--postures", "elbow_up", "--speeds", "0.1"]) == 0
    finally:
        os.umask(previous)
    modes = {p.name: p.stat().st_mode & 0o777 for p in (tmp_path / "d").iterdir()}
    assert set(modes.values()) == {0o640}, modes
