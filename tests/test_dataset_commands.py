"""`impactqp dataset validate|generate` and `impactqp diagnose` on the command line."""

import json
import os
import shutil
from collections import Counter

import pytest

from impactqp.scenarios.cli import main
from impactqp.sim.plant import PlantParameters

from cli_checks import one_line_bad_input
from conftest import JOINTS, g1_dataset


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("data") / "armature"
    plant = tmp_path_factory.mktemp("plant") / "plant.json"
    plant.write_text(json.dumps({"armature": [0.5] * JOINTS}))
    assert main(["dataset", "generate", str(out), "--plant", str(plant), "--postures", "elbow_up,elbow_left",
                 "--speeds", "0.1,0.18", "--seed", "2", "--json"]) == 0
    return out


def test_generate_then_validate(small_dataset, capsys):
    code, out, _ = run(capsys, "dataset", "validate", small_dataset, "--json")
    assert code == 0
    report = json.loads(out)
    assert report["valid"] and set(report["problems"]) == {"dataset", "t0000", "t0001", "t0002", "t0003"}


def test_validate_reports_problems_with_exit_code_1(small_dataset, tmp_path, capsys):
    broken = tmp_path / "broken"
    shutil.copytree(small_dataset, broken)
    (broken / "t0001_force.csv").unlink()
    code, out, _ = run(capsys, "dataset", "validate", broken, "--json")
    assert code == 1
    problems = json.loads(out)["problems"]
    assert problems["t0001"] and not problems["t0000"]


def test_validating_a_huge_manifest_reads_each_file_once_and_shows_progress(small_dataset, tmp_path, capsys,
                                                                            monkeypatch):
    """3,000 entries naming the same trial files: each file is read and its impact measured once
    (the work per entry is constant); stdout is the JSON alone and, stderr not a terminal, no
    progress bar is drawn on it."""
    from impactqp.controller.measured import dataset as dataset_module
    from impactqp.controller.measured import dataset_check

    huge = tmp_path / "huge"
    shutil.copytree(small_dataset, huge)
    manifest = json.loads((huge / "dataset.json").read_text())
    first = manifest["trials"][0]
    manifest["trials"] = [{**first, "id": f"x{i}"} for i in range(3000)] + manifest["trials"][1:]
    (huge / "dataset.json").write_text(json.dumps(manifest))
    reads, impacts = Counter(), []
    read_table, measure_impact = dataset_module._read_table, dataset_check.measure_impact
    monkeypatch.setattr(dataset_module, "_read_table", lambda path, columns: (reads.update([path.name]),
                                                                              read_table(path, columns))[1])
    monkeypatch.setattr(dataset_check, "measure_impact", lambda log: (impacts.append(1), measure_impact(log))[1])
    code, out, err = run(capsys, "dataset", "validate", huge, "--json")
    assert code == 0 and json.loads(out)["valid"]
    files = {name for t in manifest["trials"] for name in (t["file"], t["force_file"])}
    assert reads == Counter(files) and len(impacts) == len(manifest["trials"]) - 2999
    assert err == ""


def test_diagnose_json_report_and_saved_plant(small_dataset, tmp_path, capsys):
    code, out, err = run(capsys, "diagnose", small_dataset, "--json", "--report", tmp_path / "report",
                         "--save-plant", tmp_path / "fitted.json", "--jobs", "2", "--causes", "armature,payload,joint_damping")
    assert code == 0 and all(line.startswith("impactqp: diagnose: ") for line in err.splitlines())  # notes, no bar
    result = json.loads(out)
    for key in ("cause", "explained", "parameters", "baseline_error", "extended_error", "gain", "candidates",
                "trials", "skipped", "predictors", "causes", "intervals", "steps"):
        assert key in result
    assert result["cause"] == "armature" and result["explained"] and result["causes"][0] == "armature"
    assert set(result["intervals"]) == set(result["parameters"])
    assert result["steps"][0] == {**result["steps"][0], "cause": "armature", "selected": True}
    assert set(result["predictors"]) == {"classical", "classical_normal", "gm", "crb"}
    assert [c["cause"] for c in result["candidates"]] == ["armature", "payload", "joint_damping"]  # --causes
    fitted = PlantParameters.from_json(tmp_path / "fitted.json")
    assert fitted.armature[0] == pytest.approx(0.5, rel=0.2)
    assert (tmp_path / "report" / "report.md").read_text().startswith("# Impact diagnosis")
    from impactqp.scenarios.diagnosis_report import report_bytes

    written = sum(path.stat().st_size for path in (tmp_path / "report").iterdir())
    assert written <= report_bytes(2, result["trials"])  # the room asked for before the work is enough


def test_diagnose_reads_the_manifest_once_before_the_work(small_dataset, tmp_path, capsys, monkeypatch):
    """The checks before the diagnosis (the manifest's robot and tool, the room for --report) and
    the diagnosis's trial count share one read of the manifest; the work (the trials' loading)
    is stopped at its start here. Before: three reads."""
    from impactqp.controller.measured import dataset
    from impactqp.controller.model.validation import BadInputError
    from impactqp.sim.diagnosis import pipeline

    reads = []
    read_mapping = dataset.read_mapping
    monkeypatch.setattr(dataset, "read_mapping", lambda path, *args: reads.append(path) or read_mapping(path, *args))

    def stop(*args):
        raise BadInputError("stopped at the work")

    monkeypatch.setattr(pipeline, "_usable_trials", stop)
    code, _, err = run(capsys, "diagnose", small_dataset, "--report", tmp_path / "report")
    assert code == 2 and "stopped at the work" in err
    assert reads == [small_dataset / "dataset.json"]


@pytest.mark.parametrize("names, message", [("armature,gravity", "--causes: unknown cause 'gravity'; the candidates are "),
                                           ("payload, payload", "--causes: a cause is named twice")])
def test_unknown_or_repeated_causes_are_one_line_before_the_work(small_dataset, capsys, names, message):
    code, out, err = run(capsys, "diagnose", small_dataset, "--causes", names)
    assert code == 2 and out == "" and err.strip().splitlines() == [err.strip()]
    assert message in err and "diagnose: step" not in err


@pytest.mark.parametrize("option", ["--report", "--save-plant"])
def test_diagnose_without_room_for_its_output_is_refused_before_the_work(small_dataset, tmp_path, capsys, monkeypatch, option):
    """A file system without the room --report or --save-plant needs: one line naming the folder,
    exit code 2, before the diagnosis starts (no stage note) and with nothing written."""
    from impactqp.controller.measured import dataset_writer

    full = shutil.disk_usage(tmp_path)._replace(free=0)
    monkeypatch.setattr(dataset_writer.shutil, "disk_usage", lambda path: full)
    target = tmp_path / ("report" if option == "--report" else "fitted.json")
    code, out, err = run(capsys, "diagnose", small_dataset, option, target)
    assert code == 2 and out == "" and err.strip().splitlines() == [err.strip()]
    assert "MB are free" in err and "step" not in err
    assert not target.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["diagnose", "/nonexistent/dataset"], "not a directory"),
        (["dataset", "validate", "/nonexistent/dataset"], "not a directory"),
        (["dataset", "generate", "OUT", "--postures", "nowhere"], "unknown posture"),
        (["dataset", "generate", "OUT", "--speeds", "0.1,-1"], "[0.001, 3] m/s"),
        (["dataset", "generate", "OUT", "--speeds", ""], "--speeds is empty"),
        (["dataset", "generate", "OUT", "--speeds", "0.1,0.12,0.1"], "--speeds repeats 0.1"),
        (["dataset", "generate", "OUT", "--speeds", ",".join(str(0.05 + k * 1e-4) for k in range(101))], "at most 100"),
        (["campaign", "--out", "OUT", "--speeds", "0.1,0.1"], "--speeds repeats 0.1"),
        (["dataset", "generate", "OUT", "--plant", "PLANT"], "unknown plant parameter"),
        (["dataset", "import-franka", "OUT", "PLANT", "--surface-point", "0.6,0,0", "--surface-normal", "-1,0,0"],
         "not a libfranka"),
        (["dataset", "import-franka", "OUT", "/nonexistent.csv", "--surface-point", "0.6,0,0",
          "--surface-normal", "-1,0,0"], "no such libfranka log"),
        (["dataset", "import-franka", "OUT", "PLANT", "--surface-point", "0.6,0", "--surface-normal", "-1,0,0"],
         "--surface-point"),
        (["dataset", "import-franka", "OUT", "PLANT", "--surface-point", "0.6,0,0", "--surface-normal", "0,0,0"],
         "--surface-normal"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(tmp_path, capsys, args, message):
    plant = tmp_path / "plant.json"
    plant.write_text(json.dumps({"rotor_inertia": 1.0}))
    args = [str(tmp_path / "out") if a == "OUT" else str(plant) if a == "PLANT" else a for a in args]
    code, out, err = run(capsys, *args)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and message in err


@pytest.mark.parametrize("output", [
    ("--save-plant", "{data}/dataset.json"), ("--save-plant", "{data}/t0000.csv"), ("--save-plant", "{plant}"),
    ("--report", "{data}"), ("--report", "{parent}"),
])
def test_diagnose_never_writes_over_its_inputs(small_dataset, tmp_path, capsys, output):
    """An output that is an input (the manifest, a trial, the --plant file), or a folder that is
    or holds the dataset: one line and exit 2 before any work, every input byte-identical."""
    from conftest import file_digests

    plant = tmp_path / "plant.json"
    plant.write_text(json.dumps({"armature": [0.5] * JOINTS}))
    option, path = output
    path = path.format(data=small_dataset, plant=plant, parent=small_dataset.parent)
    before, plant_before = file_digests(small_dataset), plant.read_bytes()
    code, out, err = run(capsys, "diagnose", small_dataset, "--plant", plant, option, path)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "would overwrite the input" in err
    assert file_digests(small_dataset) == before and plant.read_bytes() == plant_before


def test_diagnose_without_a_manifest_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "t0000.csv").write_text("t,q1\n0,0\n")
    code, _, err = run(capsys, "diagnose", tmp_path)
    assert code == 2 and "dataset.json" in err and len(err.strip().splitlines()) == 1


def test_diagnose_of_one_trial_prints_no_candidate_table(tmp_path, capsys):
    """One trial: the nominal replay's verdict, no cause and no empty candidate table; with no
    cause named, --save-plant writes nothing and refuses in one line with exit code 2, after the
    diagnosis's output (before: exit 0 and a note)."""
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path / "data", DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    code, out, err = run(capsys, "diagnose", tmp_path / "data", "--save-plant", tmp_path / "plant.json")
    assert code == 2 and out.startswith("One trial") and "causes: none" in out
    assert not (tmp_path / "plant.json").exists()
    refusal = f"impactqp: error: --save-plant: no cause named: no plant to save; nothing written to {tmp_path / 'plant.json'}"
    assert err.strip().splitlines()[-1] == refusal and err.count("nothing written") == 1
    assert "candidate" not in out and "predictors" in out
    assert run(capsys, "diagnose", tmp_path / "data")[0] == 0  # without --save-plant: nothing refused


def test_diagnose_text_is_readable(small_dataset, capsys, monkeypatch):
    """Booleans as JSON writes them, parameters by joint group, the candidates sorted by gain; the
    step bar on a terminal, none with --quiet."""
    import impactqp.sim.diagnosis as diagnosis

    armature = [1.2] * 4 + [0.3] * 3
    summary = {
        "message": "explained", "causes": ["armature"], "explained": True, "parameters": {"armature": armature},
        "baseline_error": 0.15, "extended_error": 0.003, "gain": 0.98,
        "steps": [{"path": 0, "action": "add", "cause": "armature", "heldout_error": 0.003, "gain": 0.98,
                   "accepted": True, "selected": True}],
        "parameter_intervals": [{"parameter": "armature joints 1-4 (kg m^2)", "value": 1.2, "interval": [1.1, 1.3]}],
        "candidates": [
            {"cause": cause, "heldout_error": 0.1, "gain": gain, "parameters": {}}
            for cause, gain in (("payload", 0.03), ("armature", 0.98), ("contact", 0.36))
        ],
        "predictors": {"crb": 0.07}, "skipped": [],
        "trial_residuals": [{"id": "t0000", "residual": 1.1}, {"id": "t0001", "residual": 4.8}, {"id": "t0002", "residual": 0.9}],
        "outlier_trials": ["t0001"],
    }
    fake = type("Result", (), {"summary": lambda self: summary})()
    monkeypatch.setattr(diagnosis, "diagnose", lambda *args, **kwargs: fake)
    capsys.readouterr()  # the output of the fixture, when it runs first
    import sys

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)  # the progress bar shows on a terminal
    code, out, err = run(capsys, "diagnose", small_dataset)
    assert code == 0
    assert "diagnose" in err and "5/5" in err  # the progress bar, on stderr
    assert "explained: true" in out and "True" not in out
    assert "largest 4.80 (t0001); outliers: t0001" in out
    assert "  t0000 1.10, t0001 4.80 (stands out), t0002 0.90\n" in out  # every trial's residual
    assert "armature (kg m^2): joints 1-4 = 1.2, joints 5-7 = 0.3" in out
    assert "step 1: path 1 add    armature" in out and "selected" in out  # every path's steps
    table = out.split("candidate")[1].splitlines()[1:4]
    assert [line.split()[0] for line in table] == ["armature", "contact", "payload"]
    quiet = run(capsys, "--quiet", "diagnose", small_dataset)
    assert quiet == (0, out, "")  # --quiet: no bar, even on a terminal; the same text


def run_guarded(*args):
    """The command in its own interpreter: a regression that blocks on a FIFO fails the test at
    the guard instead of hanging the suite (the guard is not a timing requirement)."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "impactqp", *map(str, args)], capture_output=True, text=True,
                          timeout=300, stdin=subprocess.DEVNULL)
    return done.returncode, done.stdout, done.stderr


def test_a_fifo_in_place_of_a_trial_csv_is_a_problem_not_a_hang(small_dataset, tmp_path):
    import os

    data = tmp_path / "fifo"
    shutil.copytree(small_dataset, data)
    (data / "t0001.csv").unlink()
    os.mkfifo(data / "t0001.csv")
    code, out, err = run_guarded("dataset", "validate", data, "--json")
    assert code == 1 and err == ""
    problems = json.loads(out)["problems"]["t0001"]
    assert any("not a regular file" in p for p in problems)


@pytest.mark.parametrize("make, reason", [
    (lambda path: path.write_bytes(bytes(range(128, 256)) * 40), "is not a UTF-8 text file"),
    (os.mkfifo, "is not a regular file (a FIFO, a socket or a device)"),
])
def test_generating_into_a_dataset_whose_trial_file_is_not_text_is_bad_input(small_dataset, tmp_path, make, reason):
    """An existing trial file that is binary data or a FIFO (a read would wait on it): one line
    naming it, exit code 2, before any trial is made; the dataset is left as it was."""
    data = tmp_path / "data"
    shutil.copytree(small_dataset, data)
    (data / "t0000.csv").unlink()
    make(data / "t0000.csv")
    before = {p.name: p.read_bytes() for p in data.iterdir() if p.is_file()}
    code, out, err = run_guarded("dataset", "generate", data, "--postures", "elbow_up", "--speeds", "0.1")
    one_line_bad_input(code, out, err, f"the trial file {data / 't0000.csv'} {reason}")
    assert {p.name: p.read_bytes() for p in data.iterdir() if p.is_file()} == before
    assert sorted(p.name for p in data.iterdir()) == sorted(p.name for p in small_dataset.iterdir())


def test_a_fifo_given_to_import_franka_is_bad_input(tmp_path):
    import os

    log = tmp_path / "log.csv"
    os.mkfifo(log)
    code, out, err = run_guarded("dataset", "import-franka", tmp_path / "out", log, "--surface-point", "0.6,0,0",
                                 "--surface-normal", "-1,0,0")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "not a regular file" in err


def test_a_fifo_as_plant_file_is_bad_input(tmp_path):
    import os

    plant = tmp_path / "plant.json"
    os.mkfifo(plant)
    code, out, err = run_guarded("dataset", "generate", tmp_path / "out", "--plant", plant, "--postures", "elbow_up",
                                 "--speeds", "0.1")
    assert code == 2 and err.count("\n") == 1 and "not a regular file" in err


def test_a_g1_dataset_validates_and_diagnose_refuses_it(tmp_path, capsys):
    g1_dataset(tmp_path)
    code, out, _ = run(capsys, "dataset", "validate", tmp_path, "--json")
    assert code == 0 and json.loads(out) == {"valid": True, "problems": {"dataset": [], "g": []}}
    for args in ([], ["--robot", "fr3"]):
        code, out, err = run(capsys, "diagnose", tmp_path, *args)
        assert code == 2 and err.count("\n") == 1 and "is a g1 dataset" in err


def test_import_franka_refuses_an_output_folder_that_holds_an_input_log(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    log = out / "log.csv"
    log.write_text("not read: the output is refused first\n")
    code, stdout, err = run(capsys, "dataset", "import-franka", out, log, "--surface-point", "0.6,0,0",
                            "--surface-normal", "-1,0,0")
    assert code == 2 and stdout == "" and "would overwrite the input" in err and len(err.strip().splitlines()) == 1
    assert log.read_text() == "not read: the output is refused first\n" and sorted(out.iterdir()) == [log]


def test_progress_bars_stay_off_a_stream_that_is_not_a_terminal(tmp_path, capsys):
    """A progress bar is drawn only on a terminal: redirected, stderr keeps only real messages."""
    code, out, err = run(capsys, "dataset", "generate", tmp_path / "d", "--postures", "elbow_up", "--speeds", "0.1")
    assert code == 0 and "wrote 1 trial(s)" in out and err == ""


def test_diagnose_reports_its_stages_in_order_and_quiet_silences_them(tmp_path, capsys):
    """Progress on stderr while diagnose works: its five steps in order, each candidate model set
    of the search between the third and the fourth, each profile between the fourth and the
    fifth, then the refusal of --save-plant (no cause named: exit code 2, one line); --quiet
    leaves only that line, --verbose adds debug lines; stdout (--json) is byte-identical at the
    three levels. Two candidates (--causes) are enough for the lines."""
    from impactqp.sim.diagnosis.pipeline import STEPS
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path / "data", DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.15]))
    runs = {}
    for level in ("", "--quiet", "--verbose"):
        args = [level] if level else []
        runs[level] = run(capsys, *args, "diagnose", tmp_path / "data", "--json", "--save-plant", tmp_path / "p.json",
                          "--causes", "joint_damping,armature")
        assert runs[level][0] == 2, runs[level][2]
    assert runs[""][1] == runs["--quiet"][1] == runs["--verbose"][1] and json.loads(runs[""][1])["causes"] == []
    lines = runs[""][2].splitlines()
    assert all(line.startswith("impactqp: ") and "debug" not in line for line in lines)
    steps = [next(i for i, line in enumerate(lines) if line.startswith(f"impactqp: diagnose: step {k}/5 {step}"))
             for k, step in enumerate(STEPS, start=1)]
    assert steps == sorted(steps) and steps[0] == 0
    candidates = [i for i, line in enumerate(lines) if line.startswith("impactqp: diagnose: candidate model ")]
    assert [lines[i].split()[4:] for i in candidates] == [["1/2", "armature"], ["2/2", "joint_damping"]]
    assert steps[2] < candidates[0] and candidates[-1] < steps[3]
    profiles = [i for i, line in enumerate(lines) if line.startswith("impactqp: diagnose: profile ")]
    assert profiles and steps[3] < profiles[0] and profiles[-1] < steps[4]
    refusal = "impactqp: error: --save-plant: no cause named: no plant to save"
    assert lines[-1].startswith(refusal) and not any(line.startswith(refusal) for line in lines[:-1])
    assert runs["--quiet"][2].splitlines() == lines[-1:]
    verbose = runs["--verbose"][2].splitlines()
    assert any(line.startswith("impactqp: debug: diagnose: ") for line in verbose)
    assert [line for line in verbose if not line.startswith("impactqp: debug: ")] == lines


def test_dq_step_quantises_the_generated_dq_and_comes_once(tmp_path, capsys):
    """--dq-step sets the plant's sensor_velocity_step at every joint: the manifest declares it;
    a plant that quantises already, given --dq-step as well, is one line of bad input."""
    args = ("dataset", "generate", "--postures", "elbow_up", "--speeds", "0.1", "--dq-step", "0.004")
    code, _, _ = run(capsys, *args[:2], tmp_path / "quantised", *args[2:], "--json")
    assert code == 0
    assert json.loads((tmp_path / "quantised" / "dataset.json").read_text())["encoder_step"] == [0.004] * JOINTS
    plant = tmp_path / "plant.json"
    plant.write_text(json.dumps({"sensor_velocity_step": [0.002] * JOINTS}))
    code, out, err = run(capsys, *args[:2], tmp_path / "twice", *args[2:], "--plant", plant)
    assert code == 2 and out == "" and err.count("\n") == 1 and "give the step once" in err, err
    assert not (tmp_path / "twice").exists()


def test_diagnose_refuses_a_robot_other_than_its_manifests(tmp_path, capsys):
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--robot", "fr3", "--tool", "franka_hand")
    assert code == 2 and out == ""
    assert "manifest (panda, impact_tip) differ from --robot/--tool (fr3, franka_hand)" in err


def test_a_dataset_beyond_the_trial_limit_is_refused_with_its_count_before_any_work(tmp_path, capsys):
    speeds = ",".join(f"{0.05 + 0.002 * i:.3f}" for i in range(50))  # 3 postures x 50 speeds x 100 repeats
    code, out, err = run(capsys, "dataset", "generate", str(tmp_path / "big"), "--speeds", speeds, "--repeats", "100")
    one_line_bad_input(code, out, err, "the dataset has 15,000 trials (3 postures x (50 speeds + 0 tangential) x 100 repeats), more than the limit of 1,000")
    assert "--max-trials 15000" in err and not (tmp_path / "big").exists()


def test_diagnose_refuses_a_dataset_beyond_the_trial_limit_and_runs_within_it(tmp_path, capsys):
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.12]))
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--max-trials", "1", "--json")
    one_line_bad_input(code, out, err, "has 2 trials, more than the limit of 1")
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--max-trials", "2", "--json")
    assert code == 0, err
    assert json.loads(out)["trials"] == 2
