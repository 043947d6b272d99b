"""The command line's error boundary (``scenarios.cli.main``): bad input is one line with exit code
2, an internal error exit code 1, a stop signal exit code 130 at any moment (and none once the
work is done), the log levels, the installed entry point; every command runs for both arms, and
what does not apply to the G1 is bad input."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cli_checks import run
from process_watch import catches, console_script, mapped, runs
from impactqp.scenarios.cli import main
from impactqp.scenarios.cli.exit_codes import EXIT_BAD_INPUT, EXIT_INTERRUPTED


def test_console_script_exit_code():
    """The installed entry point returns 2 and prints no traceback."""
    proc = subprocess.run(
        [sys.executable, "-m", "impactqp", "predict", "--posture", "x", "--normal", "1,0,0", "--speed", "1"],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "unknown posture" in proc.stderr


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
