"""`impactqp max-speed` (scenarios/cli/max_speed_command.py): one path for every robot, the
arm's and the G1's JSON contracts, and the text made from the report."""

import json
import math

import numpy as np
import pytest

from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.max_speed_command import max_speed_text


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_max_speed_json_contract(capsys, monkeypatch):
    """... and the request builds the robot's model once in this process (the postures, the
    start's check and the search share it; each worker process builds its own)."""
    from impactqp.controller.model import robot as robot_module

    built = []
    build = robot_module.RobotModel.__init__
    monkeypatch.setattr(robot_module.RobotModel, "__init__", lambda self, *a, **k: built.append(1) or build(self, *a, **k))
    code, stdout, _ = run(
        capsys, "max-speed", "--posture", "elbow_left", "--tolerance", "0.05", "--jobs", "2", "--json"
    )
    assert code == 0 and len(built) == 1
    report = json.loads(stdout)
    assert report["posture"] == "elbow_left"
    assert set(report["predicted_max_speed"]) == {"classical", "gm", "crb", "robust"}
    assert report["predicted_max_speed"]["robust"] == min(report["predicted_max_speed"][m] for m in ("classical", "gm", "crb"))
    for binding in report["binding"].values():
        assert binding["criterion"] in {"velocity_pre", "velocity_post", "impulsive_torque"}
        assert 1 <= binding["joint"] <= len(report["q_impact"])
    assert report["qp_limited_speed"] == pytest.approx(report["predicted_max_speed"]["crb"], rel=0.05)
    assert report["evaluations"]


def test_max_speed_g1_json(capsys):
    code, out, _ = run(capsys, "max-speed", "--robot", "g1", "--posture", "close", "--tolerance", "0.4", "--json")
    assert code == 0
    report = json.loads(out)
    assert {"posture", "q_impact", "normal", "predicted_max_speed", "binding", "simulated_max_speed",
            "evaluations"} <= set(report)
    assert set(report["predicted_max_speed"]) == {"classical", "gm", "crb", "robust"}
    assert report["predicted_max_speed"]["robust"] == min(report["predicted_max_speed"][m] for m in ("classical", "gm", "crb"))
    speeds = [e["reference_speed"] for e in report["evaluations"] if not e["violated"]]
    assert report["simulated_max_speed"] == max(speeds)


def test_the_text_of_an_arm_report_names_each_joint_that_binds_and_each_impact():
    report = {
        "posture": "p", "jump_model": "crb",
        "predicted_max_speed": {"crb": 0.25, "robust": 0.2},
        "binding": {"crb": {"criterion": "velocity_post", "joint": 4}, "robust": {"criterion": "velocity_pre", "joint": 2}},
        "qp_limited_speed": 0.24, "qp_max_velocity_ratio": 0.9, "qp_max_torque_ratio": 0.5,
        "simulated_max_speed": 0.3,
        "evaluations": [{"reference_speed": v, "contact_speed": v, "max_velocity_ratio": v, "max_torque_ratio": v,
                         "violated": v > 0.3} for v in (0.1, 0.3, 0.5)],
    }
    lines = max_speed_text(report).splitlines()
    assert lines[0] == "p: highest feasible contact speed (m/s), jump constraints crb"
    assert "  crb           0.2500  velocity_post, joint 4" in lines
    assert "  robust        0.2000  velocity_pre, joint 2" in lines
    assert lines[4].startswith("QP-limited") and "0.2400" in lines[4]
    assert "3 simulated impacts" in lines[5]
    assert [line.split()[-1] for line in lines[-3:]] == ["False", "False", "True"]


def test_the_text_of_a_stance_report_names_where_each_criterion_binds():
    report = {
        "robot": "g1", "posture": "close",
        "predicted_max_speed": {"crb": 0.5, "gm": None},
        "binding": {"crb": {"criterion": "capture", "where": "edge 2"}, "gm": {"criterion": "", "where": ""}},
        "simulated_max_speed": 0.7, "simulated_contact_speed": 0.45, "simulated_failed_first": "",
    }
    lines = max_speed_text(report).splitlines()
    assert lines[0] == "close (g1): highest feasible contact speed (m/s)"
    assert "  crb           0.5000  capture (edge 2)" in lines
    assert lines[3] == f"  gm          {math.inf:8.4f}   ()"
    assert lines[-1] == "simulated       0.7000  commanded; contact 0.4500; failed first above: -"


def test_max_speed_with_friction_is_the_closed_form_of_the_robust_friction_rows(capsys):
    code, stdout, _ = run(
        capsys, "max-speed", "--posture", "elbow_up", "--friction", "0.3", "--tangential", "0,0.05,0", "--json"
    )
    assert code == 0
    report = json.loads(stdout)
    assert (report["friction"], report["pyramid_edges"], report["tangential"]) == (0.3, 4, [0.0, 0.05, 0.0])
    speeds, without = report["predicted_max_speed"], report["frictionless_max_speed"]
    assert set(speeds) == {"classical", "gm", "crb", "robust"}
    assert speeds["robust"] == min(speeds[m] for m in ("classical", "gm", "crb"))
    assert all(speeds[m] <= without[m] for m in speeds)
    for binding in report["binding"].values():
        assert binding["criterion"] in {"velocity_pre", "velocity_post", "impulsive_torque"}
        assert binding["mode"] in {"slip", "stick", "reversal"}
    code, text, _ = run(capsys, "max-speed", "--posture", "elbow_up", "--friction", "0.3", "--tangential", "0,0.05,0")
    assert code == 0 and "robust friction rows" in text and f"{speeds['crb']:8.4f}" in text


def test_g1_max_speed_with_friction_is_the_closed_form_of_its_stances(capsys):
    """--robot g1 --friction without --controller qp: per stance the closed form under the robust
    friction rows (``friction_max_speed``, no simulation), each predictor at most its frictionless
    closed form (mu = 0), which is ``max_speed``'s, and what binds it: a held-contact criterion or a
    joint, on one vertex."""
    from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
    from impactqp.controller.model.max_speed import Setting, closed_form_max_speed
    from impactqp.controller.model.robot import RobotModel

    code, stdout, _ = run(capsys, "max-speed", "--robot", "g1", "--posture", "parallel,step", "--friction", "0.3",
                          "--tangential", "0,0.1,0", "--json")
    assert code == 0
    reports = json.loads(stdout)["stances"]
    assert [r["posture"] for r in reports] == ["parallel", "step"]
    g1 = RobotModel("g1")
    for report in reports:
        assert (report["friction"], report["pyramid_edges"], report["tangential"]) == (0.3, 4, [0.0, 0.1, 0.0])
        speeds, without = report["predicted_max_speed"], report["frictionless_max_speed"]
        assert speeds["robust"] == min(speeds[m] for m in ("classical", "gm", "crb"))
        assert all(0.0 < speeds[m] <= without[m] for m in speeds)
        for method, binding in report["binding"].items():
            assert binding["criterion"] in {"joint_velocity", "foot_slip", "foot_lift", "capture"}
            assert binding["block"] in {"frictionless", "edge 0", "edge 1", "edge 2", "edge 3"}
            assert binding["mode"] in {"slip", "stick", "reversal"}
        q = stance_posture(g1, STANCES[report["posture"]])
        frictionless = closed_form_max_speed(g1, g1.terms(q), [-1.0, 0.0, 0.0], Setting("crb"))
        assert without["crb"] == pytest.approx(frictionless.speed, rel=1e-12)  # crb's impulse does not see the slide
    code, text, _ = run(capsys, "max-speed", "--robot", "g1", "--posture", "step", "--friction", "0.3")
    assert code == 0 and text.startswith("step (g1): highest normal contact speed") and "no friction" in text


@pytest.mark.parametrize(("stances", "friction"), [("parallel", "0.3"), ("wide,step", "0.6"), ("parallel", None)])
def test_the_qp_driven_search_with_friction_checks_against_the_frictional_closed_form(capsys, monkeypatch, stances, friction):
    """--controller qp --friction MU: per stance the checks are asked at QP_CHECKS times crb's closed
    form under the robust friction rows of mu = MU at that stance (``frictional_max_speed``, no slide),
    and the report (``checks_reference``) and its text name that closed form; without --friction the
    reference is the frictionless crb closed form (the search's own)."""
    from impactqp.controller.model.friction_max_speed import frictional_max_speed
    from impactqp.controller.model.friction_pyramid import FrictionRows
    from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
    from impactqp.controller.model.max_speed import Setting
    from impactqp.controller.model.robot import RobotModel
    from impactqp.scenarios import max_speed_search, stance_evaluation
    from impactqp.scenarios.cli.max_speed_command import QP_CHECKS

    asked = {}

    def search(robot, stance, setting, tolerance, source, checks):
        """Records the checks and the trials' rows; one feasible trial per asked speed."""
        asked[stance] = (checks, source.friction)
        q = stance_posture(robot, robot.description.stances[stance])
        predicted = max_speed_search.predicted_speeds(robot, q, setting, ("classical", "gm", "crb"))
        reference = predicted["crb"].speed if checks.reference is None else checks.reference

        def trial(speed):
            return stance_evaluation.StanceEvaluation(speed, speed, 0.5, 0.0, 0.0, False, "")

        return stance_evaluation.StanceMaxSpeed(stance, q, predicted, 1.0, 1.0, "", [trial(1.0)],
                                               {f: trial(f * reference) for f in checks.factors})

    monkeypatch.setattr(max_speed_search, "search_stance", search)
    given = ["--friction", friction] if friction else []
    code, out, _ = run(capsys, "max-speed", "--robot", "g1", "--controller", "qp", "--posture", stances, *given, "--json")
    assert code == 0
    data = json.loads(out)
    reports = data.get("stances", [data])
    assert [r["posture"] for r in reports] == stances.split(",") == list(asked)
    g1 = RobotModel("g1")
    for report in reports:
        checks, rows = asked[report["posture"]]
        assert checks.factors == QP_CHECKS
        reference = report["checks_reference"]
        if friction is None:
            assert checks.reference is None and rows is None
            assert reference["closed_form"] == "frictionless" and reference["speed"] == report["predicted_max_speed"]["crb"]
            continue
        q = stance_posture(g1, STANCES[report["posture"]])
        expected = frictional_max_speed(g1, g1.terms(q), [-1.0, 0.0, 0.0], np.zeros(3), Setting("crb"), FrictionRows(float(friction)))
        assert rows == float(friction) and checks.reference == pytest.approx(expected.max_speed.speed, rel=1e-12)
        assert reference == {"closed_form": "frictional", "method": "crb", "friction": float(friction),
                             "speed": checks.reference, "criterion": expected.max_speed.criterion,
                             "where": expected.max_speed.where, "block": expected.block}
        lines = max_speed_text(report).splitlines()
        assert lines[-4].startswith(f"  {'crb, mu ' + friction:<12}{checks.reference:8.4f}  ")
        assert lines[-4].endswith("the frictional closed form")
        assert "commanded by the QP with friction rows" in lines[-3]


def test_a_figure_of_another_format_is_refused_before_the_search(capsys, monkeypatch, tmp_path):
    from impactqp.scenarios.cli import max_speed_command

    def searched(*args, **kwargs):
        raise AssertionError("the search ran before --figure was refused")

    monkeypatch.setattr(max_speed_command, "run_max_speed", searched)
    code, out, err = run(capsys, "max-speed", "--posture", "elbow_up", "--figure", str(tmp_path / "speed.jpg"))
    assert code == 2 and out == "" and err.count("\n") == 1 and "--figure writes a figure" in err
    assert list(tmp_path.iterdir()) == []


def test_the_qp_driven_search_of_a_stance_holds_the_contact_speed_at_its_closed_form(capsys):
    """--controller qp: the trials are the whole-body QP's; asked for 1.3 times the closed form,
    the QP's governor caps the hand's target at it and the QP holds the contact speed at or below
    it, its impact rows tight before the contact; the text gives each check's asked speed (and
    target when capped), contact speed, binding rows, onsets and fall."""
    code, out, _ = run(capsys, "max-speed", "--robot", "g1", "--controller", "qp", "--posture", "close",
                       "--tolerance", "0.4", "--json")
    assert code == 0
    report = json.loads(out)
    assert report["controller"] == "qp" and set(report["checks"]) == {"0.9", "1.3"}
    closed_form = report["predicted_max_speed"]["crb"]
    for factor, check in report["checks"].items():
        assert check["reference_speed"] == pytest.approx(float(factor) * closed_form)
    above = report["checks"]["1.3"]
    assert above["contact_speed"] <= closed_form and above["not_ok"] == 0
    assert report["checks"]["0.9"]["speed_target"] == pytest.approx(0.9 * closed_form, rel=1e-12)
    assert above["speed_target"] == pytest.approx(closed_form, rel=1e-12)  # the governor's cap
    assert above["binding"] and all(name.split("[")[0] in {"post_impact_velocity", "capture_region", "foot_wrench"}
                                    for name in above["binding"].split(", "))
    lines = max_speed_text(report).splitlines()
    assert "commanded by the QP" in lines[-3]
    assert lines[-1].startswith(f"  1.3x crb: asked {above['reference_speed']:.4f} (target {above['speed_target']:.4f}), "
                                f"contact {above['contact_speed']:.4f}; "
                                f"binding: {above['binding']}; onsets: ")


def test_the_controller_option_is_a_standing_robot_s(capsys):
    code, _, err = run(capsys, "max-speed", "--posture", "elbow_up", "--controller", "qp")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--controller" in err


@pytest.mark.parametrize("robot", [[], ["--robot", "g1", "--posture", "parallel"]])
def test_the_feedback_option_is_the_whole_body_qp_s(capsys, robot):
    """--feedback chooses the state the standing robot's QP is given: without --controller qp (an
    arm, or a stance driven by its scripted arm) it is one line of bad input."""
    code, _, err = run(capsys, "max-speed", *(robot or ["--posture", "elbow_up"]), "--feedback", "blended")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--feedback" in err


@pytest.mark.parametrize("given", [
    ["--posture", "elbow_up", "--governor", "0.9"],
    ["--robot", "g1", "--posture", "parallel", "--governor", "0.9"],
    ["--robot", "g1", "--posture", "parallel", "--controller", "qp", "--governor", "0"],
    ["--robot", "g1", "--posture", "parallel", "--controller", "qp", "--governor", "nan"],
    ["--robot", "g1", "--posture", "parallel", "--controller", "qp", "--governor", "fast"],
])
def test_the_governor_option_is_the_whole_body_qp_s_and_a_positive_share(capsys, given):
    """--governor caps the standing robot's QP speed target: without --controller qp, or not 'off'
    nor a finite share > 0, it is one line of bad input."""
    code, out, err = run(capsys, "max-speed", *given)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--governor" in err


@pytest.mark.parametrize("share, expected", [("off", None), ("1.0", 1.0), ("0.95", 0.95)])
def test_the_governor_reaches_the_qp_of_every_trial(capsys, monkeypatch, share, expected):
    from impactqp.scenarios import max_speed_search

    sources = []

    def search(robot, stance, setting, tolerance, source, **options):
        sources.append(source)
        raise max_speed_search.BadInputError("searched")

    monkeypatch.setattr(max_speed_search, "search_stance", search)
    code, _, err = run(capsys, "max-speed", "--robot", "g1", "--posture", "step", "--controller", "qp", "--governor", share)
    assert code == 2 and "searched" in err
    assert [s.governor for s in sources] == [expected]


@pytest.mark.parametrize("given", [[], ["--tolerance", "0.3"]])
def test_a_stance_s_bisection_runs_to_its_own_tolerance_unless_one_is_given(capsys, monkeypatch, given):
    """The standing robot's bisection on the commanded speed stops at ``STANCE_TOLERANCE`` (0.02
    m/s) unless --tolerance is given (the arm's default, 0.005, would add two rounds of trials)."""
    from impactqp.scenarios import max_speed_search

    asked = []

    def search(robot, stance, setting, tolerance, **options):
        asked.append(tolerance)
        raise max_speed_search.BadInputError("searched")

    monkeypatch.setattr(max_speed_search, "search_stance", search)
    code, _, err = run(capsys, "max-speed", "--robot", "g1", "--posture", "step", "--controller", "qp", *given)
    assert code == 2 and "searched" in err
    assert asked == [0.3 if given else max_speed_search.STANCE_TOLERANCE]
