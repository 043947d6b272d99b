"""A franky-sim server in its own process group, for the tests that drive a robot through the
real Franka network protocol (``franky_sim_main.py``).

``FrankySimServer`` starts the server with a wall and the contact tool in its scene, waits
until its sockets listen (polling a ready file a bounded number of times, failing with the
server's own output when it does not come up) and always stops it: ``stop`` kills the whole
process group and waits for it, ``__exit__`` calls it, and the pytest fixtures that own a
server call it in their finalizer, so a failing test leaves no server behind.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from impactqp.controller.model.robot import TOOL_CENTRE_OFFSET, TOOL_RADIUS

SCRIPT = Path(__file__).with_name("franky_sim_main.py")
READY_POLLS = 1200  # 0.1 s apart: importing MuJoCo and Pinocchio is slow on a loaded machine
POLL_INTERVAL = 0.1


def csv(values) -> str:
    return ",".join(repr(float(x)) for x in np.asarray(values, float).ravel())


class FrankySimServer:
    """The server process; ``hostname`` is the loopback address it serves once started."""

    def __init__(self, directory: Path, wall_point, wall_normal, q0, tool: bool = True):
        self.directory = Path(directory)
        self.ready_file = self.directory / "franky-sim.ready"
        self.output = self.directory / "franky-sim.log"
        self.args = [str(self.ready_file), csv(wall_point), csv(wall_normal), csv(q0)]
        if tool:
            self.args += [repr(TOOL_CENTRE_OFFSET), repr(TOOL_RADIUS)]
        self.process: subprocess.Popen | None = None
        self.hostname: str | None = None

    def start(self) -> str:
        with open(self.output, "wb") as output:
            self.process = subprocess.Popen(
                [sys.executable, str(SCRIPT), *self.args],
                stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True,
            )
        for _ in range(READY_POLLS):
            if self.ready_file.exists():
                self.hostname = self.ready_file.read_text()
                return self.hostname
            if self.process.poll() is not None:
                break
            time.sleep(POLL_INTERVAL)
        self.stop()
        tail = self.output.read_text(errors="replace")[-2000:]
        raise RuntimeError(f"franky-sim did not start listening (exit code {self.process.returncode}):\n{tail}")

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self) -> None:
        """Kill the server's process group (the server and anything it started) and reap it."""
        if self.process is None:
            return
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait()

    def __enter__(self) -> FrankySimServer:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
