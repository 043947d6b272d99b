"""``impactqp postures`` and ``predict`` (``scenarios.cli.commands``): JSON keys, readable tables,
one-line errors with exit code 2, the FR3 and another tool, ``predict --robot g1`` (a stance of
the floating base); the group's default output folders."""

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from cli_checks import one_line_bad_input, run
from conftest import JOINTS, g1_model
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.robot_description import PANDA
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT


def test_postures_json(capsys):
    code, out, _ = run(capsys, "postures", "--json")
    assert code == 0
    rows = json.loads(out)
    assert [r["name"] for r in rows] == list(PANDA.postures)
    for r in rows:
        assert {"name", "q", "contact_point", "normal"} <= set(r)
        assert len(r["q"]) == JOINTS and len(r["contact_point"]) == 3
        assert np.linalg.norm(r["normal"]) == pytest.approx(1.0)


def test_predict_json_contract(capsys):
    code, out, _ = run(
        capsys, "predict", "--posture", "elbow_up", "--normal", "-2,0,0", "--speed", "0.15",
        "--tangential", "0,0.05,0", "--restitution", "0.2", "--json",
    )
    assert code == 0
    report = json.loads(out)
    np.testing.assert_allclose(report["normal"], [-1, 0, 0])
    np.testing.assert_allclose(report["pre_impact_velocity"], [0.15, 0.05, 0.0])
    assert report["restitution"] == 0.2
    assert set(report["methods"]) == {"classical", "classical_normal", "gm", "crb"}
    assert np.array(report["methods"]["crb"]["W"]).shape == (3, 3)


def test_predict_with_q_and_one_method(capsys):
    q = ",".join(str(x) for x in PANDA.postures["elbow_left"].q)
    code, out, _ = run(capsys, "predict", "--q", q, "--normal", "-1,0,0", "--speed", "0.1", "--method", "gm", "--json")
    assert code == 0
    assert list(json.loads(out)["methods"]) == ["gm"]


def test_predict_table(capsys):
    code, out, _ = run(capsys, "predict", "--posture", "elbow_right", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == 0
    for name in ("classical", "classical_normal", "gm", "crb", "cond(M)"):
        assert name in out
    assert "e-0" not in out and "e+0" not in out


@pytest.mark.parametrize(
    "command", [["postures"], ["predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1"]]
)
def test_contact_points_are_written_with_four_decimals(capsys, command):
    """The JSON keeps full precision; the text shows each coordinate to 0.1 mm, never 7.9491e-08."""
    code, out, _ = run(capsys, *command, "--json")
    points = [r["contact_point"] for r in (json.loads(out) if command == ["postures"] else [json.loads(out)])]
    code, out, _ = run(capsys, *command)
    assert code == 0
    lines = [line for line in out.splitlines() if "contact point" in line]
    assert len(lines) == len(points)
    for line, point in zip(lines, points):
        cells = line.split("[")[1].split("]")[0].split(", ")
        assert all(len(cell.split(".")[1]) == 4 for cell in cells)
        np.testing.assert_allclose([float(c) for c in cells], point, atol=0.5e-4)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--q", "0,0,0,-1,0,1.5,nan"], "non-finite"),
        (["--q", "0,0,0,-1,0,1.5"], f"{JOINTS} values"),
        (["--q", "0,0,0,-5,0,1.5,0"], "outside the joint limits"),
        (["--q", "-0.63343,3e-05,1.5708,-0.467,0.0,3.01097,2.8973"], "singular"),
        (["--posture", "nowhere"], "unknown posture"),
        (["--posture", "elbow_up", "--normal", "0,0,0"], "zero"),
        (["--posture", "elbow_up", "--speed", "0"], r"\(0, 3\] m/s"),
        (["--posture", "elbow_up", "--speed", "-0.1"], r"\(0, 3\] m/s"),
        (["--posture", "elbow_up", "--restitution", "1.2"], r"\[0, 1\]"),
        (["--posture", "elbow_up", "--tangential", "0.1,0,0"], "orthogonal"),
        (["--normal", "-1,0,0", "--speed", "0.1"], "exactly one"),
    ],
)
def test_bad_input_is_one_line_with_exit_code_2(capsys, args, message):
    defaults = {"--normal": "-1,0,0", "--speed": "0.1"}
    full = list(args)
    for flag, value in defaults.items():
        if flag not in full:
            full += [flag, value]
    code, out, err = run(capsys, "predict", *full)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    import re

    assert re.search(message, err)


@pytest.mark.parametrize("speed", ["1e308", "50", "-1", "nan"])
def test_speed_outside_the_physical_range_is_bad_input(capsys, speed):
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", speed, "--json")
    one_line_bad_input(code, out, err, "m/s")
    assert out == ""


def test_postures_and_predict_of_the_fr3(capsys):
    """`postures --robot fr3` lists the FR3's named postures with their q and contact point;
    `predict --robot fr3 --method gm` prints W = J M^-1 J^T (22) of the FR3's own model, which
    is not the Panda's."""
    from impactqp.controller.model.robot import RobotModel
    from impactqp.controller.model.robot_description import ROBOTS

    FR3 = ROBOTS["fr3"]

    code, out, _ = run(capsys, "postures", "--robot", "fr3", "--json")
    assert code == 0
    rows = json.loads(out)
    fr3 = RobotModel("fr3")
    assert [r["name"] for r in rows] == list(FR3.postures)
    for r in rows:
        np.testing.assert_array_equal(r["q"], FR3.postures[r["name"]].q)
        np.testing.assert_allclose(r["contact_point"], fr3.contact_point(r["q"]), atol=1e-12)
    W = {}
    for robot in ("panda", "fr3"):
        code, out, _ = run(
            capsys, "predict", "--robot", robot, "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1",
            "--method", "gm", "--json",
        )
        assert code == 0
        W[robot] = np.array(json.loads(out)["methods"]["gm"]["W"])
    terms = fr3.terms(FR3.postures["elbow_up"].q)
    np.testing.assert_allclose(W["fr3"], terms.J @ np.linalg.solve(terms.M, terms.J.T), rtol=1e-9, atol=1e-12)
    assert not np.allclose(W["fr3"], W["panda"], rtol=1e-3)


def test_the_postures_of_another_tool_put_its_contact_point_on_the_wall(capsys):
    code, out, _ = run(capsys, "postures", "--robot", "fr3", "--tool", "franka_hand", "--json")
    assert code == 0
    for r in json.loads(out):
        assert r["contact_point"][0] == pytest.approx(0.6, abs=1e-4)  # the default wall x = 0.6 m


def test_predict_g1_json(capsys):
    code, out, _ = run(capsys, "predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0",
                       "--speed", "0.3", "--json")
    assert code == 0
    report = json.loads(out)
    assert {"q", "contact_point", "normal", "pre_impact_velocity", "restitution", "cond_M", "methods"} <= set(report)
    assert set(report["methods"]) == {"classical", "gm", "crb"}
    for entry in report["methods"].values():
        assert len(entry["dq_jump"]) == g1_model().model.nv and len(entry["feet_impulse"]) == 12
        assert np.asarray(entry["impulse"]) @ [-1.0, 0.0, 0.0] > 0.0


def test_predict_g1_takes_a_configuration(capsys):
    q = ",".join(f"{x:g}" for x in pin.neutral(g1_model().model))  # the base at the origin, upright
    code, out, _ = run(capsys, "predict", "--robot", "g1", "--q", q, "--normal", "-1,0,0", "--speed", "0.2",
                       "--method", "gm", "--json")
    assert code == 0 and list(json.loads(out)["methods"]) == ["gm"]
    zero = pin.neutral(g1_model().model)
    zero[3:7] = 0.0  # no orientation at all
    huge = pin.neutral(g1_model().model)
    huge[10] = 1e308
    for bad in (zero, huge):
        code, out, err = run(capsys, "predict", "--robot", "g1", "--q", ",".join(f"{x:g}" for x in bad),
                             "--normal", "-1,0,0", "--speed", "0.2")
        assert code == EXIT_BAD_INPUT and out == "" and len(err.strip().splitlines()) == 1


def test_stances_are_the_g1_postures():
    assert {"parallel", "wide", "staggered", "close", "far"} <= set(STANCES)


def _commands(group, path=()):
    """(name path, click command) of every command of the group, its subgroups' included."""
    import click

    for name, command in group.commands.items():
        if isinstance(command, click.Group):
            yield from _commands(command, (*path, name))
        else:
            yield (*path, name), command


def test_every_default_output_folder_is_out_slash_the_command():
    """One convention: a command that writes a folder by default writes ``out/<command>`` under
    the current directory (read from the click parameters: --out, --log, an OUT argument)."""
    from impactqp.scenarios.cli.commands import cli

    defaults = {
        path: str(param.default)
        for path, command in _commands(cli)
        for param in command.params
        if param.name in ("out", "out_dir", "log") and isinstance(param.default, (str, Path))
    }
    assert set(defaults) == {("demo",), ("run",), ("campaign",), ("sweep",), ("oblique",), ("dataset", "generate")}
    for path, default in defaults.items():
        assert default == f"out/{path[-1]}", (path, default)
