"""Stop signals against every long command (issue 31): SIGINT, SIGTERM and SIGHUP, each sent at
moments observed in the process (its handlers in, a heavy library mapped, its work under way,
its work done), to the console script a user runs. Each case requires exit code 130 (or 0 when
the work had finished first, with its output complete), one line ``impactqp: interrupted`` and
no traceback, no partial output (no temporary file; a dataset, a sweep or a report left is
complete), and no process of the command (pool workers, Ray's raylet, GCS and workers
included) alive a few seconds after its end.

The cost is bounded: tiny problems, and one signal per (command, moment), the three signals
rotating over the moments so that each command gets every signal (SIGHUP included) and each
moment every signal across the commands.
"""

from __future__ import annotations

import importlib.util
import json
import signal
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pytest

from impactqp.scenarios.sweep.config import EXAMPLE
from process_watch import WatchedCommand, catches, children, descendants, mapped, runs

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the process state in /proc")

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
GRACE = 15.0
"""s the processes of a command may take to end after it has ended: 'a few seconds later'."""
INTERRUPTED = "impactqp: interrupted"


def _tiny_sweep() -> str:
    """The example sweep cut down to two cells, searched at a coarse tolerance."""
    text = EXAMPLE
    for old, new in (("origin = [0.6, -0.2, 0.5]", "origin = [0.6, -0.05, 0.5]"), ("size = [0.4, 0.3]", "size = [0.1, 0.0]"),
                     ('jump_models = ["gm", "crb"]', 'jump_models = ["crb"]'), ("tolerance = 0.005", "tolerance = 0.05")):
        assert old in text
        text = text.replace(old, new)
    return text


SWEEP_CONFIG = _tiny_sweep()


@dataclass(frozen=True)
class LongCommand:
    """A long command: its arguments (``{out}``, ``{dataset}``, ``{config}`` filled in), the
    moment its work is under way, the library whose loading is its heavy start-up, and what its
    output holds once complete (``check(out, finished)``: ``finished`` when the command said it
    had done its work)."""

    args: tuple[str, ...]
    working: Callable[[WatchedCommand], bool]
    heavy: str
    check: Callable[[Path, bool], None]


def _dataset_left(out: Path, finished: bool, trials: int) -> None:
    """A dataset left in ``out`` validates; a finished command's holds all its trials."""
    from impactqp.controller.measured.dataset import load_manifest
    from impactqp.controller.measured.dataset_check import validate

    if not (out / "dataset.json").exists():
        assert not finished and not (out.exists() and any(out.glob("*.csv"))), "trial files without a manifest"
        return
    problems = validate(out)
    assert not any(problems.values()), problems
    assert not finished or len(load_manifest(out / "dataset.json")["trials"]) == trials


def _campaign_left(out: Path, finished: bool) -> None:
    _dataset_left(out, finished, 2)
    if finished:
        assert (out / "table1.json").exists() and (out / "table1.md").exists()


def _sweep_left(out: Path, finished: bool) -> None:
    """A sweep left in ``out`` reads (its chunks are whole Parquet files); a finished one has
    every cell."""
    from impactqp.scenarios.sweep import store

    if not (out / store.CONFIG_FILE).exists():
        assert not finished and not (out.exists() and any(out.glob("chunk-*"))), "chunks without a sweep"
        return
    json.loads((out / store.CONFIG_FILE).read_text())
    if any(out.glob("chunk-*.parquet")):
        table = store.read_table(out)
        assert not finished or table.num_rows == 2
    else:
        assert not finished


def _report_left(out: Path, finished: bool) -> None:
    assert not finished or (out / "report.md").exists()


def _run_log_left(out: Path, finished: bool) -> None:
    _dataset_left(out, finished, 1)


def _workers_started(command: WatchedCommand) -> bool:
    return bool(children(command.pid))


def _ray_started(command: WatchedCommand) -> bool:
    return any("raylet" in line for line in descendants(command.pid, command.token).values())


def _said(text: str) -> Callable[[WatchedCommand], bool]:
    return lambda command: any(text in line for line in command.stderr)


def _exists(name: str) -> Callable[[WatchedCommand], bool]:
    return lambda command: (command.cwd / name).exists()


COMMANDS = {
    "generate": LongCommand(
        ("dataset", "generate", "{out}", "--postures", "elbow_up", "--speeds", "0.08,0.1,0.12,0.15", "--jobs", "2",
         "--json"),
        _workers_started, "mujoco", lambda out, finished: _dataset_left(out, finished, 4),
    ),
    "campaign": LongCommand(
        ("campaign", "--postures", "elbow_up", "--speeds", "0.1,0.12", "--tangential", "none", "--out", "{out}",
         "--json"),
        _exists("out/dataset.json"), "mujoco", _campaign_left,
    ),
    "sweep": LongCommand(
        ("sweep", "{config}", "--simulate", "--jobs", "2", "--out", "{out}", "--json"),
        _workers_started, "mujoco", _sweep_left,
    ),
    "sweep-ray": LongCommand(
        ("sweep", "{config}", "--backend", "ray", "--jobs", "1", "--out", "{out}", "--json"),
        _ray_started, "_raylet", _sweep_left,
    ),
    "diagnose": LongCommand(
        ("diagnose", "{dataset}", "--causes", "armature,payload", "--report", "{out}", "--json"),
        _said("step 3/5"), "mujoco", _report_left,
    ),
    "run": LongCommand(
        ("run", "--backend", "sim", "--unpaced", "--duration", "0.5", "--log", "{out}", "--json"),
        _exists("out"), "mujoco", _run_log_left,
    ),
}


def _json_done(command: WatchedCommand) -> bool:
    """The command printed its whole result (one JSON document on stdout): its work is done."""
    text = "".join(command.stdout)
    if not text.endswith("\n"):
        return False
    try:
        json.loads(text)
    except ValueError:
        return False
    return True


MOMENTS = ("handlers", "heavy", "working", "done")


def _moment(name: str, long: LongCommand) -> Callable[[WatchedCommand], bool]:
    marker = "--json"  # in the command's arguments: it runs the command, not a copy of the test worker
    return {
        "handlers": lambda c: runs(c.pid, marker) and catches(c.pid, signal.SIGTERM),
        "heavy": lambda c: runs(c.pid, marker) and mapped(c.pid, long.heavy),
        "working": long.working,
        "done": _json_done,
    }[name]


def _cases():
    for i, name in enumerate(COMMANDS):
        marks = [pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="Ray is not installed")] if (
            name == "sweep-ray") else []
        for j, moment in enumerate(MOMENTS):
            sig = SIGNALS[(i + j) % len(SIGNALS)]
            yield pytest.param(name, moment, sig, marks=marks, id=f"{name}-{moment}-{sig.name}")


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory) -> Path:
    """A two-trial dataset for ``diagnose``."""
    from impactqp.scenarios.cli import main

    out = tmp_path_factory.mktemp("signals") / "dataset"
    assert main(["--quiet", "dataset", "generate", str(out), "--postures", "elbow_up", "--speeds", "0.1,0.12"]) == 0
    return out


def test_every_command_gets_every_signal_and_every_moment_gets_every_signal():
    cases = [p.values for p in _cases()]
    for name in COMMANDS:
        assert {sig for n, _, sig in cases if n == name} == set(SIGNALS)
    for moment in MOMENTS:
        assert {sig for _, m, sig in cases if m == moment} == set(SIGNALS)


@pytest.mark.parametrize(("name", "moment", "sig"), list(_cases()))
def test_a_stop_signal_ends_the_command_with_one_line_no_partial_output_and_no_process_left(
    tmp_path, name, moment, sig, small_dataset
):
    long = COMMANDS[name]
    (tmp_path / "sweep.toml").write_text(SWEEP_CONFIG)
    fill = {"out": "out", "dataset": str(small_dataset), "config": "sweep.toml"}
    command = WatchedCommand([arg.format(**fill) for arg in long.args], cwd=tmp_path)
    try:
        reached = command.wait_for(_moment(moment, long), moment)
        assert reached or moment == "done", f"{name} ended before the moment {moment!r}: {''.join(command.stderr)}"
        if reached:
            command.proc.send_signal(sig)
        code = command.finish()
        left = command.survivors(GRACE)
    finally:
        command.kill_all()
    stdout, stderr = "".join(command.stdout), "".join(command.stderr)
    assert "Traceback" not in stderr and "Fatal Python error" not in stderr, stderr
    assert not left, f"alive {GRACE} s after the end of {name}: {left}"
    finished = _json_done(command)
    braked = False
    if code == 0:
        assert moment == "done" and finished and INTERRUPTED not in stderr, stderr
    else:
        assert code == 130, stderr
        lines = [line for line in stderr.splitlines() if "interrupted" in line]
        braked = name == "run" and finished
        if braked:  # the loop braked to a stop and kept its log (a complete trial or none): the report says so
            assert len(lines) == 1 and lines[0].startswith("impactqp: warning: interrupted: braked to a stop"), stderr
        else:
            assert stderr.splitlines()[-1:] == [INTERRUPTED] and lines == [INTERRUPTED], stderr
            assert finished or stdout == "", stdout
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")], "a temporary file is left"
    long.check(tmp_path / "out", finished and not braked)
