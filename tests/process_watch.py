"""Watching a command line process from the outside, through /proc (Linux): the moments a stop
signal is sent at are observed in the process (its handlers, its mapped libraries, its children,
what it printed), never guessed from a clock, and the processes it leaves behind are found by
its session and by a token in the environment every descendant inherits (a process that made a
session of its own, as a daemon does, still carries it)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

PROC = Path("/proc")
TOKEN_VARIABLE = "IMPACTQP_TEST_PROCESS_TOKEN"
HANG_GUARD = 300.0
"""s a watched command may take at most: a guard against a hang, not a moment of the test."""


def caught_signals(pid: int) -> int:
    """The process's mask of signals with a handler (SigCgt)."""
    for line in (PROC / str(pid) / "status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return int(line.split()[1], 16)
    return 0


def catches(pid: int, sig: int) -> bool:
    return caught_signals(pid) & (1 << (sig - 1)) != 0


def mapped(pid: int, name: str) -> bool:
    """Whether a file whose path holds ``name`` (a library) is mapped in the process."""
    return name in (PROC / str(pid) / "maps").read_text()


def runs(pid: int, marker: str) -> bool:
    """Whether the process already runs the command whose arguments hold ``marker``: between
    fork and exec it is a copy of the test worker, with the worker's libraries mapped and whatever
    handlers the worker's extensions put in, and a signal caught there is lost when exec replaces
    the image."""
    return marker in (PROC / str(pid) / "cmdline").read_bytes().decode(errors="replace")


def _stat(pid: str) -> tuple[str, int, int, int] | None:
    """(state, parent, process group, session) of a process; None once it is gone."""
    try:
        text = (PROC / pid / "stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return fields[0], int(fields[1]), int(fields[2]), int(fields[3])


def _carries(pid: str, token: str) -> bool:
    try:
        return f"{TOKEN_VARIABLE}={token}".encode() in (PROC / pid / "environ").read_bytes().split(b"\0")
    except OSError:
        return False


def descendants(session: int, token: str) -> dict[int, str]:
    """The living processes (zombies left out) of the session ``session`` or carrying ``token``
    in their environment: pid -> command line."""
    alive = {}
    for entry in PROC.iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        stat = _stat(entry.name)
        if stat is None or stat[0] == "Z":
            continue
        if stat[3] == session or stat[2] == session or _carries(entry.name, token):
            try:
                alive[int(entry.name)] = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
    return alive


def children(pid: int) -> list[int]:
    """The living processes whose parent is ``pid``."""
    found = []
    for entry in PROC.iterdir():
        if entry.name.isdigit():
            stat = _stat(entry.name)
            if stat is not None and stat[0] != "Z" and stat[1] == pid:
                found.append(int(entry.name))
    return found


def console_script() -> list[str]:
    """The installed ``impactqp`` console script (what a user runs), else ``python -m impactqp``."""
    script = Path(sys.executable).with_name("impactqp")
    return [str(script)] if script.exists() else [sys.executable, "-m", "impactqp"]


class WatchedCommand:
    """``impactqp ARGS`` in a session of its own (``start_new_session``), with a token in its
    environment, SIGINT at its default disposition (not the test runner's), and its stdout and
    stderr read as they come by two threads."""

    def __init__(self, args: list[str], cwd: Path):
        self.cwd = cwd
        self.token = uuid.uuid4().hex
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self.proc = subprocess.Popen(
            [*console_script(), *args], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=os.environ | {TOKEN_VARIABLE: self.token}, start_new_session=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        self.pid = self.proc.pid
        self._readers = [
            threading.Thread(target=self._read, args=(stream, lines), daemon=True)
            for stream, lines in ((self.proc.stdout, self.stdout), (self.proc.stderr, self.stderr))
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream, lines: list[str]) -> None:
        for line in stream:
            lines.append(line)

    def wait_for(self, moment, what: str) -> bool:
        """Poll ``moment(self)`` until it holds (True) or the command has ended (False)."""
        start = time.monotonic()
        while self.proc.poll() is None:
            try:
                if moment(self):
                    return True
            except OSError:  # the process went away while it was read
                pass
            assert time.monotonic() - start < HANG_GUARD, f"no {what} in {HANG_GUARD} s"
            time.sleep(0.002)
        return False

    def finish(self) -> int:
        """Wait for the command's end and for its output to be read; its exit code."""
        try:
            code = self.proc.wait(timeout=HANG_GUARD)
        except subprocess.TimeoutExpired:
            self.kill_all()
            raise
        for reader in self._readers:
            reader.join(timeout=HANG_GUARD)
        return code

    def survivors(self, grace: float) -> dict[int, str]:
        """The processes of the command still alive ``grace`` seconds after its end at the latest
        (returned as soon as there are none)."""
        end = time.monotonic() + grace
        while (alive := descendants(self.pid, self.token)) and time.monotonic() < end:
            time.sleep(0.05)
        return alive

    def kill_all(self) -> None:
        """SIGKILL to every process of the command: the test's cleanup after a failure."""
        for pid in [self.pid, *descendants(self.pid, self.token)]:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
