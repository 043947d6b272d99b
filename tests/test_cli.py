"""The command-line contract: JSON keys, readable tables, one-line errors with exit code 2; ``predict
--robot g1`` (a stance of the floating base) and what does not apply to the G1."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from conftest import JOINTS, g1_model
from process_watch import catches, console_script, mapped, runs
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.robot_description import PANDA
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT, EXIT_INTERRUPTED


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


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


def test_console_script_exit_code():
    """The installed entry point returns 2 and prints no traceback."""
    proc = subprocess.run(
        [sys.executable, "-m", "impactqp", "predict", "--posture", "x", "--normal", "1,0,0", "--speed", "1"],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "unknown posture" in proc.stderr


def one_line_bad_input(code, out, err, fragment):
    assert code == 2, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert fragment in err


def test_plant_that_is_a_directory_is_bad_input(capsys, tmp_path):
    code, out, err = run(capsys, "max-speed", "--posture", "elbow_up", "--plant", str(tmp_path))
    one_line_bad_input(code, out, err, "is a directory, not a file")


def test_output_directory_that_is_a_file_is_bad_input(capsys, tmp_path):
    existing = tmp_path / "taken"
    existing.write_text("keep me")
    code, out, err = run(capsys, "campaign", "--out", str(existing), "--speeds", "0.1", "--tangential", "none")
    one_line_bad_input(code, out, err, "not a directory")
    assert existing.read_text() == "keep me"



@pytest.mark.parametrize(
    "command",
    [
        ("campaign", "--out", "", "--speeds", "0.1", "--tangential", "none"),
        ("campaign", "--out", "  ", "--speeds", "0.1", "--tangential", "none"),
        ("dataset", "generate", "", "--speeds", "0.1"),
        ("simulate", "--posture", "elbow_up", "--speed", "0.1", "--video", ""),
        ("demo", "--out", ""),
    ],
    ids=["campaign", "campaign-blank", "generate", "video", "demo"],
)
def test_an_empty_output_path_is_bad_input_and_nothing_lands_in_the_working_directory(
    capsys, tmp_path, monkeypatch, command
):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *command)
    one_line_bad_input(code, out, err, "is empty")
    assert list(tmp_path.iterdir()) == []

def test_output_under_a_file_is_bad_input(capsys, tmp_path):
    existing = tmp_path / "file"
    existing.write_text("x")
    code, out, err = run(capsys, "dataset", "generate", str(existing / "sub"), "--speeds", "0.1")
    one_line_bad_input(code, out, err, "not a directory")


@pytest.mark.parametrize("speed", ["1e308", "50", "-1", "nan"])
def test_speed_outside_the_physical_range_is_bad_input(capsys, speed):
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", speed, "--json")
    one_line_bad_input(code, out, err, "m/s")
    assert out == ""


def test_an_internal_error_is_not_reported_as_bad_input(capsys, monkeypatch):
    import impactqp.controller.model.prediction as prediction

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(prediction, "predict_all", broken)
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == 1
    assert "internal error" in err and "--debug" in err and "Traceback" not in err
    code, out, err = run(capsys, "--debug", "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == 1
    assert "Traceback" in err and "ZeroDivisionError" in err


def test_version_is_the_installed_one(capsys):
    from importlib import metadata

    code, out, _ = run(capsys, "--version")
    assert code == 0 and out.strip() == f"impactqp, version {metadata.version('impactqp')}"


HEAVY = ("numpy", "click", "scipy", "pinocchio", "numba", "mujoco", "impactqp.controller")


def test_the_entry_point_installs_its_handlers_before_any_heavy_import():
    """What the console script does (import main, call it), with signal.signal watched: when the
    SIGTERM handler goes in, none of the seconds of imports has run yet."""
    code = (
        "import signal, sys\n"
        "real, seen = signal.signal, []\n"
        "def watch(sig, handler):\n"
        f"    if sig == signal.SIGTERM and not seen: seen.append([m for m in {HEAVY!r} if m in sys.modules])\n"
        "    return real(sig, handler)\n"
        "signal.signal = watch\n"
        "from impactqp.scenarios.cli import main\n"
        "assert main(['--version']) == 0\n"
        "print(seen[0])\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert proc.stdout.strip().splitlines()[-1] == "[]", proc.stdout


# Moments of the start-up, each observed in the process rather than guessed from a clock: its
# handlers are in (the earliest moment the contract covers: before, Python itself is starting),
# numpy's or MuJoCo's library is being loaded, the output directory exists (trials are running).
MOMENTS = {
    "handlers": lambda pid, out: runs(pid, str(out)) and catches(pid, signal.SIGTERM),
    "numpy": lambda pid, out: runs(pid, str(out)) and mapped(pid, "numpy"),
    "mujoco": lambda pid, out: runs(pid, str(out)) and mapped(pid, "mujoco"),
    "writing": lambda pid, out: out.exists(),
}


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the process state in /proc")
@pytest.mark.parametrize("moment", list(MOMENTS))
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_during_start_up_exits_130_without_a_traceback_or_partial_output(tmp_path, sig, moment):
    out = tmp_path / "d"
    proc = subprocess.Popen(
        [*console_script(), "dataset", "generate", str(out), "--postures", "elbow_up", "--speeds", "0.08,0.1,0.12,0.15,0.18",
         "--repeats", "3", "--jobs", "1", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # not the test runner's disposition
    )
    try:
        while not MOMENTS[moment](proc.pid, out):
            assert proc.poll() is None, f"the command ended before the moment {moment!r}: {proc.stderr.read()}"
            time.sleep(0.002)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_INTERRUPTED, stderr
    assert "Traceback" not in stderr and stderr.strip().splitlines() == ["impactqp: interrupted"], stderr
    assert stdout == ""
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]  # no temporary file left
    if (out / "dataset.json").exists():  # every trial the manifest lists is complete
        assert main(["dataset", "validate", str(out), "--json"]) == 0


def test_a_stop_signal_that_an_extension_wrapped_is_still_an_interruption(capsys, monkeypatch):
    """A signal in the initialisation of a C extension (MuJoCo's, pybind11) comes out as an
    ImportError("initialization failed") whose context is the KeyboardInterrupt: exit code 130."""
    import impactqp.controller.model.prediction as prediction

    def wrapped(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ImportError("initialization failed")  # noqa: B904 - as the extension does

    monkeypatch.setattr(prediction, "predict_all", wrapped)
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == EXIT_INTERRUPTED and err.strip() == "impactqp: interrupted" and out == ""


def test_the_progress_callback_drives_a_tqdm_bar():
    """``bar_progress``: the demo's stage-2 bar follows generate_dataset's progress(done, total)."""
    import io

    from tqdm import tqdm

    from impactqp.scenarios.cli.arguments import bar_progress

    with tqdm(file=io.StringIO()) as bar:
        progress = bar_progress(bar)
        for done in (1, 2, 6):
            progress(done, 6)
            assert (bar.n, bar.total) == (done, 6)


# ---------------------------------------------------------------------------- --robot / --tool
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


def test_diagnose_refuses_a_robot_other_than_its_manifests(tmp_path, capsys):
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up"], speeds=[0.1]))
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--robot", "fr3", "--tool", "franka_hand")
    assert code == 2 and out == ""
    assert "manifest (panda, impact_tip) differ from --robot/--tool (fr3, franka_hand)" in err



def test_a_request_beyond_the_trial_limit_is_refused_with_its_count_before_any_work(tmp_path, capsys):
    speeds = ",".join(f"{0.05 + 0.002 * i:.3f}" for i in range(50))  # 3 postures x 50 speeds x 100 repeats
    code, out, err = run(capsys, "dataset", "generate", str(tmp_path / "big"), "--speeds", speeds, "--repeats", "100")
    one_line_bad_input(code, out, err, "the dataset has 15,000 trials (3 postures x (50 speeds + 0 tangential) x 100 repeats), more than the limit of 1,000")
    assert "--max-trials 15000" in err and not (tmp_path / "big").exists()
    code, out, err = run(capsys, "campaign", "--out", str(tmp_path / "c"), "--postures", "elbow_up", "--speeds", "0.1,0.12", "--tangential", "none", "--max-trials", "1")
    one_line_bad_input(code, out, err, "the campaign has 2 trials (1 posture x 2 speeds + 0 tangential), more than the limit of 1")
    assert not (tmp_path / "c").exists()
    code, out, err = run(capsys, "campaign", "--out", str(tmp_path / "c"), "--speeds", "0.1", "--max-trials", "0")
    one_line_bad_input(code, out, err, "--max-trials must be a whole number >= 1")


def test_diagnose_refuses_a_dataset_beyond_the_trial_limit_and_runs_within_it(tmp_path, capsys):
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    generate_dataset(tmp_path, DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.12]))
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--max-trials", "1", "--json")
    one_line_bad_input(code, out, err, "has 2 trials, more than the limit of 1")
    code, out, err = run(capsys, "diagnose", str(tmp_path), "--max-trials", "2", "--json")
    assert code == 0, err
    assert json.loads(out)["trials"] == 2

@pytest.mark.parametrize("args, message", [
    (["--robot", "kuka"], "unknown robot 'kuka'; choose from panda, fr3, ur5, g1"),
    (["--tool", "hammer"], "unknown tool 'hammer'"),
    (["--tool", "absent.toml"], "the tool file absent.toml does not exist"),
])
def test_a_bad_robot_or_tool_is_one_line_and_exit_2(capsys, args, message):
    code, out, err = run(capsys, "postures", *args)
    assert code == 2 and out == "" and message in err and len(err.strip().splitlines()) == 1


SWEEP_CONFIG = """\
[grid]
origin = [0.6, 0.0, 0.7]
u = [0.0, 1.0, 0.0]
v = [0.0, 0.0, 1.0]
size = [0.0, 0.0]
spacing = 0.1
[settings]
normals = [[-1.0, 0.0, 0.0]]
restitution = [0.0]
jump_models = ["crb"]
seed_posture = "elbow_up"
[controller]
jump_model = ["crb"]
impact_duration = [0.015]
[simulate]
tolerance = 0.005
"""


def _smoke_commands(tmp):
    (tmp / "sweep.toml").write_text(SWEEP_CONFIG)
    return {
        "predict": ["predict", "--posture", "elbow_left", "--normal", "-1,0,0", "--speed", "0.1", "--json"],
        "postures": ["postures", "--json"],
        "simulate": ["simulate", "--posture", "elbow_up", "--speed", "0.1", "--out", str(tmp / "sim"), "--json"],
        "campaign": ["campaign", "--postures", "elbow_up", "--speeds", "0.1", "--tangential", "none",
                     "--out", str(tmp / "campaign"), "--json"],
        "max-speed": ["max-speed", "--posture", "elbow_up", "--tolerance", "0.2", "--json"],
        "dataset generate": ["dataset", "generate", str(tmp / "data"), "--postures", "elbow_up", "--speeds", "0.1",
                             "--json"],
        "sweep": ["sweep", str(tmp / "sweep.toml"), "--out", str(tmp / "sweep"), "--json"],
        "run": ["run", "--unpaced", "--duration", "0.3", "--log", str(tmp / "run"), "--json"],
        "diagnose": ["diagnose", str(tmp / "measured"), "--jobs", "2", "--json"],
    }


@pytest.mark.parametrize("robot, tool", [("panda", "impact_tip"), ("fr3", "franka_hand")])
@pytest.mark.parametrize("command", ["predict", "postures", "simulate", "campaign", "max-speed", "dataset generate",
                                     "sweep", "run", "diagnose"])
def test_every_command_runs_for_both_robots(tmp_path, capsys, robot, tool, command):
    """Each command with --robot and --tool exits 0 with JSON; the datasets it writes record
    that robot and that tool; diagnose models the robot and the tool of its dataset."""
    from impactqp.controller.measured.dataset import read_dataset
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.controller.model.tool_description import TOOLS
    from impactqp.sim.generation import DatasetRequest, generate_dataset

    if command == "diagnose":
        request = DatasetRequest(postures=["elbow_up"], speeds=[0.1, 0.15], choice=RobotChoice.of(robot, tool))
        generate_dataset(tmp_path / "measured", request)

    code, out, err = run(capsys, *_smoke_commands(tmp_path)[command], "--robot", robot, "--tool", tool)
    assert code == 0, err
    json.loads(out)
    for written in ("sim", "campaign", "data", "run"):
        if (tmp_path / written / "dataset.json").exists():
            header = read_dataset(tmp_path / written).header
            assert header.robot == robot and header.tool.as_dict() == TOOLS[tool].as_dict()


def test_a_stop_signal_whose_interrupt_a_library_swallowed_still_ends_the_command(capsys, monkeypatch):
    """A KeyboardInterrupt that code swallows (an optional import's ``except`` around a C
    extension the signal interrupted) is raised again until the command line catches it: exit
    code 130, without running the command on."""
    import os
    import time

    import impactqp.controller.model.prediction as prediction

    ran_on = []

    def swallowing(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)  # the handler raises in here
        except KeyboardInterrupt:
            pass  # swallowed
        time.sleep(5.0)  # the re-raised interrupt ends this
        ran_on.append(True)

    monkeypatch.setattr(prediction, "predict_all", swallowing)
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == EXIT_INTERRUPTED and err.strip() == "impactqp: interrupted" and out == "" and not ran_on
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_after_the_work_is_done_keeps_the_exit_code(sig):
    """The console entry point (``main()`` without argv): a stop signal that comes once the
    command has finished, while the interpreter shuts down, neither kills the process by the
    signal nor prints anything: the command's own exit code stands."""
    script = (
        "import os, signal, sys, time\n"
        "from impactqp.scenarios.cli import main\n"
        "code = main()\n"
        f"os.kill(os.getpid(), {int(sig)})\n"
        "time.sleep(0.2)\n"
        "sys.exit(code)\n"
    )
    done = subprocess.run([sys.executable, "-c", script, "postures", "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) and done.stderr == ""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_while_main_puts_its_handlers_back_does_not_escape_it(capsys, monkeypatch, sig):
    """A signal that comes once the command is done, while ``main`` cancels its redelivery timer
    and puts the handlers back (its ``finally``): the exit code stands, no KeyboardInterrupt
    escapes ``main`` (a traceback at the console) and no line is printed."""
    real_setitimer = signal.setitimer
    sent = []

    def signal_then_setitimer(*args):
        if not sent:
            sent.append(sig)
            os.kill(os.getpid(), sig)
        return real_setitimer(*args)

    monkeypatch.setattr(signal, "setitimer", signal_then_setitimer)
    code, out, err = run(capsys, "postures", "--json")
    assert sent == [sig] and code == 0 and json.loads(out) and err == ""


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


@pytest.mark.parametrize("args", [
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--wall-point", "1,0,0"),
    ("max-speed", "--robot", "g1", "--posture", "parallel", "--jump-model", "gm"),
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--jump-model", "gm"),
    ("simulate", "--robot", "g1", "--posture", "parallel", "--speed", "0.2", "--controller", "qp",
     "--jump-model", "robust"),
    ("simulate", "--posture", "elbow_right", "--speed", "0.1", "--controller", "qp"),
    ("predict", "--robot", "g1", "--posture", "parallel", "--normal", "-1,0,0", "--speed", "0.2", "--tool", "pad"),
    ("campaign", "--robot", "g1", "--postures", "kneeling"),
    ("postures", "--robot", "g1"),
])
def test_what_does_not_apply_to_the_g1_is_one_line_of_bad_input(capsys, args):
    code, out, err = run(capsys, *args)
    assert code == EXIT_BAD_INPUT
    assert err.count("\n") == 1 and err.startswith("impactqp: error:")


def test_stances_are_the_g1_postures():
    assert {"parallel", "wide", "staggered", "close", "far"} <= set(STANCES)


def test_verbose_and_quiet_together_are_bad_input(capsys):
    code, out, err = run(capsys, "--verbose", "--quiet", "postures", "--json")
    assert code == EXIT_BAD_INPUT and out == "" and err.strip().splitlines() == [err.strip()]
    assert "at most one of --verbose and --quiet" in err


@pytest.mark.parametrize("level", [[], ["--quiet"], ["--verbose"]])
def test_bad_input_stays_one_line_at_every_level_and_the_log_is_removed_after(capsys, level):
    """The bad-input line and exit code 2 at every level (--verbose: never a traceback), and no
    handler is left on the package's logger once the command is over."""
    import logging

    logger = logging.getLogger("impactqp")
    before = (list(logger.handlers), logger.level)
    code, out, err = run(capsys, *level, "predict", "--posture", "nope", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == EXIT_BAD_INPUT and out == "" and "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("impactqp: error: unknown posture 'nope'")
    assert all(line.startswith("impactqp: debug: ") for line in err.strip().splitlines()[:-1])
    assert (list(logger.handlers), logger.level) == before


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


def test_a_stop_signal_raised_where_python_cannot_propagate_it_is_no_message(capsys, monkeypatch):
    """The handler's KeyboardInterrupt raised inside a weakref callback (as in importlib's module
    locks) cannot propagate: Python hands it to ``sys.unraisablehook`` ("Exception ignored in
    ..."). While ``main`` runs it is dropped there, and raised again until caught: exit 130, the
    one line, nothing handed to the hook that was in place."""
    import gc
    import os
    import time
    import weakref

    import impactqp.controller.model.prediction as prediction

    unraisable = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)

    def interrupted_in_a_callback(*args, **kwargs):
        class Held:
            pass

        held = Held()
        reference = weakref.ref(held, lambda ref: (os.kill(os.getpid(), signal.SIGINT), time.sleep(1.0)))
        del held
        gc.collect()
        time.sleep(5.0)  # the interrupt is raised again in here
        return reference

    monkeypatch.setattr(prediction, "predict_all", interrupted_in_a_callback)
    code, out, err = run(capsys, "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1")
    assert code == EXIT_INTERRUPTED and err.strip() == "impactqp: interrupted" and out == ""
    assert unraisable == [] and sys.unraisablehook == unraisable.append  # the caller's hook is back


def test_a_stop_signal_once_the_json_result_is_out_leaves_the_exit_code(capsys, monkeypatch):
    """The JSON on stdout is the command's result: a stop signal right after it (before the
    command returns) neither turns the exit code into 130 nor prints a line."""
    import os
    import time

    import impactqp.scenarios.cli.commands as commands

    real = commands.emit_json

    def then_a_signal(obj):
        real(obj)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.5)  # the handler runs in here

    monkeypatch.setattr(commands, "emit_json", then_a_signal)
    code, out, err = run(capsys, "postures", "--json")
    assert code == 0 and json.loads(out) and err == ""


def test_a_stop_signal_while_the_json_result_is_written_leaves_the_exit_code(capsys, monkeypatch):
    """A stop signal that lands while the JSON result is being written (the signal matrix's
    `run` case, SIGHUP as the JSON appeared) lets the write finish: the whole JSON, exit code 0,
    no line."""
    import os
    import time

    import click

    real = click.echo
    signalled = []

    def a_signal_then_the_write(message=None, **kwargs):
        if not signalled:
            signalled.append(True)
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(0.5)  # the handler runs in here, before the text is out
        real(message, **kwargs)

    monkeypatch.setattr(click, "echo", a_signal_then_the_write)
    code, out, err = run(capsys, "postures", "--json")
    assert signalled and code == 0 and json.loads(out) and err == ""
