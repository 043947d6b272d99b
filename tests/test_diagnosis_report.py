"""The Markdown + PNG diagnosis report (scenarios/diagnosis_report.py)."""

import mujoco

from impactqp.scenarios.diagnosis_report import write_report
from impactqp.sim.causes import PayloadCause
from impactqp.sim.diagnosis import diagnose
from impactqp.sim.generation import generate_dataset


def test_report_is_written_without_touching_other_files(tmp_path):
    mujoco.set_mju_user_warning(lambda message: None)
    generate_dataset(tmp_path / "data", postures=["elbow_up", "elbow_left"], speeds=[0.12], seed=1)
    result = diagnose(tmp_path / "data", causes=[PayloadCause()])
    path = write_report(result, tmp_path / "report")
    text = path.read_text()
    for heading in ("# Impact diagnosis", "## What the nominal simulation gets wrong", "## Candidate causes",
                    "## Predictors and simulations per condition"):
        assert heading in text
    for figure in ("jumps.png", "error_vs_speed.png", "predictor_errors.png"):
        assert (tmp_path / "report" / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "report" / "notes.txt").write_text("the user's own file")
    write_report(result, tmp_path / "report")
    assert (tmp_path / "report" / "notes.txt").read_text() == "the user's own file"
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == [
        "error_vs_speed.png", "jumps.png", "notes.txt", "predictor_errors.png", "report.md"
    ]
