"""`impactqp dataset validate|generate` and `impactqp diagnose` on the command line."""

import json
import shutil

import pytest

from impactqp.scenarios.cli import main
from impactqp.sim.plant import PlantParameters


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("data") / "armature"
    plant = tmp_path_factory.mktemp("plant") / "plant.json"
    plant.write_text(json.dumps({"armature": [0.5] * 7}))
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


def test_diagnose_json_report_and_saved_plant(small_dataset, tmp_path, capsys):
    code, out, _ = run(capsys, "diagnose", small_dataset, "--json", "--report", tmp_path / "report",
                       "--save-plant", tmp_path / "fitted.json", "--jobs", "2")
    assert code == 0
    result = json.loads(out)
    for key in ("cause", "explained", "parameters", "baseline_error", "extended_error", "gain", "candidates",
                "trials", "skipped", "predictors", "causes", "intervals", "steps"):
        assert key in result
    assert result["cause"] == "armature" and result["explained"] and result["causes"][0] == "armature"
    assert set(result["intervals"]) == set(result["parameters"])
    assert result["steps"][0] == {**result["steps"][0], "cause": "armature", "selected": True}
    assert set(result["predictors"]) == {"classical", "classical_normal", "gm", "crb"}
    fitted = PlantParameters.from_json(tmp_path / "fitted.json")
    assert fitted.armature[0] == pytest.approx(0.5, rel=0.2)
    assert (tmp_path / "report" / "report.md").read_text().startswith("# Impact diagnosis")


@pytest.mark.parametrize(
    "args, message",
    [
        (["diagnose", "/nonexistent/dataset"], "not a directory"),
        (["dataset", "validate", "/nonexistent/dataset"], "not a directory"),
        (["dataset", "generate", "OUT", "--postures", "nowhere"], "unknown posture"),
        (["dataset", "generate", "OUT", "--speeds", "0.1,-1"], "(0, 3] m/s"),
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


def test_diagnose_without_a_manifest_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "t0000.csv").write_text("t,q1\n0,0\n")
    code, _, err = run(capsys, "diagnose", tmp_path)
    assert code == 2 and "dataset.json" in err and len(err.strip().splitlines()) == 1


def test_diagnose_text_is_readable(small_dataset, capsys, monkeypatch):
    """Booleans as JSON writes them, parameters by joint group, the candidates sorted by gain."""
    import impactqp.sim.diagnosis as diagnosis

    armature = [1.2] * 4 + [0.3] * 3
    summary = {
        "message": "explained", "causes": ["armature"], "explained": True, "parameters": {"armature": armature},
        "baseline_error": 0.15, "extended_error": 0.003, "gain": 0.98,
        "steps": [{"cause": "armature", "heldout_error": 0.003, "gain": 0.98, "selected": True}],
        "parameter_intervals": [{"parameter": "armature joints 1-4 (kg m^2)", "value": 1.2, "interval": [1.1, 1.3]}],
        "candidates": [
            {"cause": cause, "heldout_error": 0.1, "gain": gain, "parameters": {}}
            for cause, gain in (("payload", 0.03), ("armature", 0.98), ("contact", 0.36))
        ],
        "predictors": {"crb": 0.07}, "skipped": [],
    }
    fake = type("Result", (), {"summary": lambda self: summary})()
    monkeypatch.setattr(diagnosis, "diagnose", lambda *args, **kwargs: fake)
    capsys.readouterr()  # the output of the fixture, when it runs first
    code, out, _ = run(capsys, "diagnose", small_dataset)
    assert code == 0
    assert "explained: true" in out and "True" not in out
    assert "armature (kg m^2): joints 1-4 = 1.2, joints 5-7 = 0.3" in out
    table = out.split("candidate")[1].splitlines()[1:4]
    assert [line.split()[0] for line in table] == ["armature", "contact", "payload"]
