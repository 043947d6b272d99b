"""A franky-sim server (the Franka network protocol in front of a MuJoCo FR3) with a wall and
the contact tool in its scene, in its own process group, for the tests and the benchmark rows
that drive a robot through the real protocol (``pip install -e '.[test]'``).

``FrankySimServer`` (the parent side) starts ``python -m impactqp.sim.franky_sim``,
waits until its sockets listen (polling its ready file a bounded number of times, failing with
the server's own output when it does not come up) and always stops it: ``stop`` kills the whole
process group and reaps it; ``__exit__`` and the tests' fixture finalizers call it, so a failing
run leaves no server behind.

``main`` (the server process): usage ``python -m impactqp.sim.franky_sim READY_FILE
WALL_POINT WALL_NORMAL Q0 [TOOL_CENTRE TOOL_RADIUS]`` (vectors as comma-separated numbers; the
tool is a sphere in the hand's frame, as the declared tool ``ToolDescription`` describes it). The
server binds the first free loopback address and writes it to READY_FILE once it listens, and
writes to READY_FILE.contact the robot time (s) of the first state sent after a physics step with
a contact on the wall (the first state the contact force acted on): libfranka stamps a state with
its message id in ms since the connection, so the server's contact time and the client's state
times share one clock. Files appear by rename, complete.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from impactqp.controller.model.tool_description import Sphere, ToolDescription, tool_description

READY_POLLS = 1200  # 0.1 s apart: importing MuJoCo and Pinocchio is slow on a loaded machine
POLL_INTERVAL = 0.1
WALL_HALF_SIZE = 1.0
WALL_HALF_THICKNESS = 0.05
HAND_BODY = "robot0_hand"


def csv(values) -> str:
    return ",".join(repr(float(x)) for x in np.asarray(values, float).ravel())


def vector(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split(",")])


def write_file(path: str, text: str) -> None:
    partial = path + ".partial"
    with open(partial, "w") as f:
        f.write(text)
    os.replace(partial, path)


class FrankySimServer:
    """The server process; ``hostname`` is the loopback address it serves once started."""

    def __init__(self, directory, wall_point, wall_normal, q0, tool: str | ToolDescription | None = "impact_tip"):
        self.directory = Path(directory)
        self.ready_file = self.directory / "franky-sim.ready"
        self.output = self.directory / "franky-sim.log"
        self.args = [str(self.ready_file), csv(wall_point), csv(wall_normal), csv(q0)]
        if tool is not None:
            tool = tool_description(tool)
            if not isinstance(tool.geometry, Sphere) or tool.frame != "hand" or tool.replaces_hand:
                raise ValueError(f"the franky-sim scene takes a sphere on the Franka Hand, not the tool {tool.name!r}")
            self.args += [csv(tool.geometry.centre), repr(tool.geometry.radius)]
        self.process: subprocess.Popen | None = None
        self.hostname: str | None = None

    def start(self) -> str:
        self.directory.mkdir(parents=True, exist_ok=True)
        with open(self.output, "wb") as output:
            self.process = subprocess.Popen(
                [sys.executable, "-m", __name__, *self.args],
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

    def contact_time(self) -> float | None:
        """Robot time (s) of the first state with the arm touching the wall, None before one."""
        path = Path(f"{self.ready_file}.contact")
        return float(path.read_text()) if path.exists() else None

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


def add_wall(sim, point: np.ndarray, normal: np.ndarray) -> None:
    """A box whose face towards the robot is the plane through ``point`` with unit ``normal``."""
    normal = normal / np.linalg.norm(normal)
    centre = point - WALL_HALF_THICKNESS * normal
    body = ET.SubElement(sim.worldbody, "body", name="wall", pos=" ".join(map(str, centre)))
    ET.SubElement(
        body, "geom", name="wall", type="box", zaxis=" ".join(map(str, normal)),
        size=f"{WALL_HALF_SIZE} {WALL_HALF_SIZE} {WALL_HALF_THICKNESS}",
    )


def add_tool(sim, centre: np.ndarray, radius: float) -> None:
    """The contact tool: a light sphere at ``centre`` in the hand's frame."""
    hand = next(body for body in sim.worldbody.iter("body") if body.get("name") == HAND_BODY)
    ET.SubElement(
        hand, "geom", name="tool", type="sphere", size=str(radius), pos=" ".join(map(str, centre)),
        mass="0.001", contype="1", conaffinity="1", group="0",
    )


def contact_recorder(server, path: str):
    """A post-step callback writing the time of the first state sent after a step with a wall contact."""
    import mujoco  # in the server process only

    def record(sim) -> None:
        if os.path.exists(path):
            return
        wall = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, "wall")
        if any(wall in (c.geom1, c.geom2) for c in sim.data.contact[: sim.data.ncon]):
            # the state sent after this step carries the server's next message id (private to it)
            message_id = server.robot_servers[0]._FrankaServer__message_id
            write_file(path, repr(message_id / 1000.0))  # as libfranka's Duration::toSec

    return record


def main() -> None:
    from franky_sim import SimulationServer  # optional: the test extra
    from franky_sim.mujoco_simulator import MujocoSimulator

    ready_file, wall_point, wall_normal, q0 = sys.argv[1:5]
    with MujocoSimulator() as sim:
        sim.add_robot(initial_q=tuple(vector(q0)))
        add_wall(sim, vector(wall_point), vector(wall_normal))
        if len(sys.argv) > 5:
            add_tool(sim, vector(sys.argv[5]), float(sys.argv[6]))
        with SimulationServer(sim) as server:
            sim.register_post_step_callback(contact_recorder(server, ready_file + ".contact"))
            write_file(ready_file, server.robot_servers[0].hostname)
            server.run_forever()


if __name__ == "__main__":
    main()
