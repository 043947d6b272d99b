"""A franky-sim server (the Franka network protocol in front of a MuJoCo FR3) with a wall and
the contact tool in its scene, in its own process group, for the tests and the benchmark rows
that drive a robot through the real protocol (``pip install -e '.[test]'``).

``FrankySimServer`` (the parent side) starts ``python -m impactqp.sim.franky_sim`` and reads
the address the server prints on its standard output once its sockets listen (a blocking read:
the line, or the end of the pipe when the server died first, then the error carries the
server's own output). ``stop`` kills the whole process group and reaps it; ``__exit__`` and the
tests' fixture finalizers call it, so a failing run leaves no server behind.

``main`` (the server process): usage ``USAGE`` (vectors as
comma-separated numbers; the tool is a sphere in the hand's frame, as the declared tool
``ToolDescription`` describes it). The server binds the first free loopback address, prints it
on its standard output once it listens, and writes to CONTACT_FILE the robot time (s) of
the first state sent after a physics step with a
contact on the wall (the first state the contact force acted on): libfranka stamps a state with
its message id in ms since the connection, so the server's contact time and the client's state
times share one clock. Beside it, ``franky-sim.collision`` (JSON) holds the collision thresholds
the client last sent (``set_collision_behavior``'s eight lists, as the server received them;
franky-sim does not simulate the reflex). Files appear by rename, complete. With ``--stop-after-commands N`` the
server stops (closes its connection and exits) when the N-th motion command arrives, before it
answers it: a connection lost at a known cycle (N > 1: a motion's first command may answer an
older state, below).

**Lockstep.** franky-sim's own loop steps its physics every millisecond of wall-clock time
whether or not a command came, and libfranka reads the newest state, so a client delayed by a
loaded machine skips states while the arm goes on with its last command: how far the arm moved
between two of our cycles, and which states a run sees, would depend on the machine's load.
Here the server steps freely (franky-sim's paced loop) only while no motion runs (connecting,
``read_once``, the model check) and at a motion's start, until the motion's first command (the
client's first ``readOnce`` of a motion needs a state newer than the one that started it, and
the arm is at rest there). From the first command on, it steps once and sends the state for
each command that answers the newest state it sent, as the ``sim`` backend's plant waits for
the controller; a command that answers an older state (the client read its state before the
last free step) is taken but not answered, since the client's next read finds the newest state
waiting. So from the motion's second command on, exactly one command and one state are in
flight: a run depends on its cycles, not on wall-clock time (only the state time between a
motion's first cycles can jump by the free steps, at rest). ``--stop-after-commands`` counts
every command of the run's motions. When no command answering the newest state has come for
``LOCKSTEP_PATIENCE`` s, the server steps and sends a state anyway, as the robot's own clock
would: on a loaded machine a run stalled there (the client's 1 s receive timeout, seen twice
in the test suite's franky-sim runs) without telling whether a datagram was lost or a command
answered a state the client had not seen; the client then reads the newer state, as libfranka
does on a robot.
"""

from __future__ import annotations

import json
import logging
import os
import select
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.model.tool_description import Sphere, ToolDescription, tool_description

USAGE = (
    "python -m impactqp.sim.franky_sim CONTACT_FILE WALL_POINT WALL_NORMAL Q0 [TOOL_CENTRE TOOL_RADIUS] "
    "[--stop-after-commands N]"
)
START_GUARD = 600.0  # s: the longest wait for a server to listen before it counts as hung
FREE_PERIOD = 1e-3  # s: franky-sim's own step period while no command is awaited
LOCKSTEP_PATIENCE = 0.5
"""s the lockstep waits for a command answering its newest state before it steps on its own
clock, as the robot would: half of libfranka's 1 s receive timeout, so that a stalled exchange
is resolved with time to spare while a client slowed by a loaded machine (a step it takes, a
sample the log then misses, which ``dataset validate`` reports) has half a second."""
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

    def __init__(
        self, directory, wall_point, wall_normal, q0, tool: str | ToolDescription | None = "impact_tip",
        stop_after_commands: int | None = None,
    ):
        self.directory = Path(directory)
        self.contact_file = self.directory / "franky-sim.contact"
        self.collision_file = self.directory / "franky-sim.collision"
        self.output = self.directory / "franky-sim.log"
        self.args = [str(self.contact_file), csv(wall_point), csv(wall_normal), csv(q0)]
        if tool is not None:
            tool = tool_description(tool)
            if not isinstance(tool.geometry, Sphere) or tool.frame != "hand" or tool.replaces_hand:
                raise ValueError(f"the franky-sim scene takes a sphere on the Franka Hand, not the tool {tool.name!r}")
            self.args += [csv(tool.geometry.centre), repr(tool.geometry.radius)]
        if stop_after_commands is not None:
            self.args += ["--stop-after-commands", str(int(stop_after_commands))]
        self.process: subprocess.Popen | None = None
        self.hostname: str | None = None

    def start(self) -> str:
        """Start the server and wait until it listens; its address."""
        self.directory.mkdir(parents=True, exist_ok=True)
        with open(self.output, "wb") as output:
            self.process = subprocess.Popen(
                [sys.executable, "-m", __name__, *self.args],
                stdout=subprocess.PIPE, stderr=output, stdin=subprocess.DEVNULL, start_new_session=True,
            )
        with self.process.stdout:
            # a hang guard only (a server that neither listens nor dies), far above any start-up
            ready, _, _ = select.select([self.process.stdout], [], [], START_GUARD)
            line = self.process.stdout.readline().decode().strip() if ready else ""  # "": it ended first
        if line:
            self.hostname = line
            return line
        self.stop()
        raise RuntimeError(f"franky-sim did not start listening (exit code {self.process.returncode}, or hung):\n{self.output_text()}")

    def output_text(self) -> str:
        """What the server wrote to its log (its standard error, and its standard output after the
        address), "" before it started."""
        return self.output.read_text(errors="replace") if self.output.exists() else ""

    def contact_time(self) -> float | None:
        """Robot time (s) of the first state with the arm touching the wall, None before one."""
        return float(self.contact_file.read_text()) if self.contact_file.exists() else None

    def collision_behavior(self) -> dict | None:
        """The collision thresholds the server last received (``record_collision_behavior``),
        None before any."""
        return json.loads(self.collision_file.read_text()) if self.collision_file.exists() else None

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


def record_collision_behavior(path: str) -> None:
    """Make the server write the thresholds of every ``SetCollisionBehavior`` command it
    receives to ``path`` (JSON: the command's eight lists by name) before answering it."""
    from franky_sim.franka_robot_protocol import SetCollisionBehaviorCommand  # in the server process only

    handle = SetCollisionBehaviorCommand.handle

    def record(command, server) -> None:
        names = [f.name for f in dataclasses.fields(command) if f.name.endswith("_thresholds_acceleration")
                 or f.name.endswith("_thresholds_nominal")]
        write_file(path, json.dumps({name: list(getattr(command, name)) for name in names}))
        handle(command, server)

    SetCollisionBehaviorCommand.handle = record


def answers_newest_state(robot_server) -> bool:
    """Whether the client's last command answers the newest state sent (libfranka stamps a
    command with the message id of the state it read; franky-sim counts its message ids)."""
    newest = robot_server._FrankaServer__message_id - 1
    return robot_server._FrankaRobotServer__current_control_command.message_id == newest


class CommandCount:
    """Counts the client's motion commands as franky-sim's server handles them, one by one (one
    ``process_commands`` may handle two when the client sent both before it ran)."""

    def __init__(self, robot_server):
        self.count = 0
        self.handle = robot_server._handle_udp_command
        robot_server._handle_udp_command = self

    def __call__(self, data: bytes) -> None:
        self.count += 1
        self.handle(data)


def serve_in_lockstep(server, stop_after_commands: int | None) -> None:
    """Run ``server`` (a franky-sim ``SimulationServer`` with one robot) until the client's
    ``stop_after_commands``-th motion command: paced free steps (franky-sim's 1 ms period) while
    no motion runs and at a motion's start, then, from the motion's first command until its
    ``motion_finished`` command, one step and one state per command that answers the newest
    state (module docstring), or after ``LOCKSTEP_PATIENCE`` s without one."""
    robot_server = server.robot_servers[0]
    commands = CommandCount(robot_server)
    lockstep = False
    while True:
        tick = time.monotonic()
        waited = False
        if lockstep:  # the command arrives on franky-sim's UDP socket, a closed connection on TCP
            sockets = [robot_server._FrankaServer__udp_socket, robot_server._tcp_socket]
            waited = not select.select(sockets, [], [], LOCKSTEP_PATIENCE)[0]
        before = commands.count
        robot_server.process_commands()
        command = commands.count > before
        if stop_after_commands is not None and commands.count >= stop_after_commands:
            logging.getLogger(__name__).info("stopping at motion command %d, before answering it", commands.count)
            return
        moving = robot_server.current_motion_id > 0
        lockstep = moving and (lockstep or command)
        if lockstep and not waited and not (command and answers_newest_state(robot_server)):
            continue  # nothing to answer: woken without a command, or the command of an older state
        server.sim.step()
        robot_server.send_state()
        if not lockstep:
            time.sleep(max(0.0, FREE_PERIOD - (time.monotonic() - tick)))


@dataclass(frozen=True)
class ServerArguments:
    """The command line of the server process (module docstring)."""

    contact_file: str
    wall_point: np.ndarray
    wall_normal: np.ndarray
    q0: np.ndarray
    tool: tuple[np.ndarray, float] | None
    stop_after_commands: int | None


def arguments(argv: list[str]) -> ServerArguments:
    """Parsed by hand: the vectors start with a minus sign, which ``argparse`` takes for an option."""
    argv = list(argv)
    stop_after = None
    if "--stop-after-commands" in argv:
        i = argv.index("--stop-after-commands")
        stop_after = int(argv[i + 1])
        del argv[i : i + 2]
    if len(argv) not in (4, 6):
        raise SystemExit(f"usage: {USAGE}")
    tool = (vector(argv[4]), float(argv[5])) if len(argv) == 6 else None
    return ServerArguments(argv[0], vector(argv[1]), vector(argv[2]), vector(argv[3]), tool, stop_after)


def main() -> None:
    from franky_sim import SimulationServer  # optional: the test extra
    from franky_sim.mujoco_simulator import MujocoSimulator

    args = arguments(sys.argv[1:])
    record_collision_behavior(str(Path(args.contact_file).with_suffix(".collision")))
    logging.basicConfig(level=logging.INFO, format="%(relativeCreated)d ms %(name)s %(levelname)s: %(message)s")
    with MujocoSimulator() as sim:
        sim.add_robot(initial_q=tuple(args.q0))
        add_wall(sim, args.wall_point, args.wall_normal)
        if args.tool is not None:
            add_tool(sim, *args.tool)
        with SimulationServer(sim) as server:
            sim.register_post_step_callback(contact_recorder(server, args.contact_file))
            print(server.robot_servers[0].hostname, flush=True)
            os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # anything printed later goes to the log
            serve_in_lockstep(server, args.stop_after_commands)


if __name__ == "__main__":
    main()
