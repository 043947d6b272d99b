"""The Markdown + PNG diagnosis report (scenarios/diagnosis_report.py)."""


from impactqp.scenarios.diagnosis_report import FeasibleSpeed, write_report
from impactqp.sim.causes import PayloadCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import DatasetRequest, generate_dataset


def test_report_is_written_without_touching_other_files(tmp_path):
    generate_dataset(tmp_path / "data", DatasetRequest(postures=["elbow_up", "elbow_left"], speeds=[0.12], seed=1))
    result = diagnose(tmp_path / "data", causes=[PayloadCause()])
    path = write_report(result, tmp_path / "report")
    text = path.read_text()
    for heading in ("# Impact diagnosis", "## What the nominal simulation gets wrong", "## Candidate causes",
                    "## Predictors and simulations per condition", "## Selection steps",
                    "## Fitted parameters and 95 % intervals"):
        assert heading in text
    assert "payload mass (kg)" in text  # the best candidate's parameters and intervals
    assert "What it means for your robot" not in text
    speeds = [FeasibleSpeed("elbow_up", 0.31, 0.42, 0.27)]
    text = write_report(result, tmp_path / "report", speeds).read_text()
    assert "| elbow_up | 0.310 | 0.420 | 0.270 |" in text
    assert "your robot can hit at 0.270 m/s, not 0.420 m/s" in text
    for figure in ("jumps.png", "error_vs_speed.png", "predictor_errors.png"):
        assert (tmp_path / "report" / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "report" / "notes.txt").write_text("the user's own file")
    write_report(result, tmp_path / "report")
    assert (tmp_path / "report" / "notes.txt").read_text() == "the user's own file"
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == [
        "error_vs_speed.png", "jumps.png", "notes.txt", "predictor_errors.png", "report.md"
    ]
