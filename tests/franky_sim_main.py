"""Runs a franky-sim server (the Franka network protocol in front of a MuJoCo FR3) with a wall
and the contact tool in its scene; started by ``franky_sim_server.FrankySimServer`` in its own
process group.

usage: python franky_sim_main.py READY_FILE WALL_POINT WALL_NORMAL Q0 [TOOL_CENTRE TOOL_RADIUS]
(vectors as comma-separated numbers). The server binds the first free loopback address, writes
it to READY_FILE (by rename, so the file appears complete) once its sockets listen, and serves
until it is killed.
"""

import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
from franky_sim import SimulationServer
from franky_sim.mujoco_simulator import MujocoSimulator

WALL_HALF_SIZE = 1.0
WALL_HALF_THICKNESS = 0.05
HAND_BODY = "robot0_hand"


def vector(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split(",")])


def add_wall(sim: MujocoSimulator, point: np.ndarray, normal: np.ndarray) -> None:
    """A box whose face towards the robot is the plane through ``point`` with unit ``normal``."""
    normal = normal / np.linalg.norm(normal)
    centre = point - WALL_HALF_THICKNESS * normal
    body = ET.SubElement(sim.worldbody, "body", name="wall", pos=" ".join(map(str, centre)))
    ET.SubElement(
        body, "geom", name="wall", type="box", zaxis=" ".join(map(str, normal)),
        size=f"{WALL_HALF_SIZE} {WALL_HALF_SIZE} {WALL_HALF_THICKNESS}",
    )


def add_tool(sim: MujocoSimulator, centre_offset: float, radius: float) -> None:
    """The contact tool: a light sphere on the hand's z axis (the axis of the fingers)."""
    hand = next(body for body in sim.worldbody.iter("body") if body.get("name") == HAND_BODY)
    ET.SubElement(
        hand, "geom", name="tool", type="sphere", size=str(radius), pos=f"0 0 {centre_offset}",
        mass="0.001", contype="1", conaffinity="1", group="0",
    )


def main() -> None:
    ready_file, wall_point, wall_normal, q0 = sys.argv[1:5]
    with MujocoSimulator() as sim:
        sim.add_robot(initial_q=tuple(vector(q0)))
        add_wall(sim, vector(wall_point), vector(wall_normal))
        if len(sys.argv) > 5:
            add_tool(sim, float(sys.argv[5]), float(sys.argv[6]))
        with SimulationServer(sim) as server:
            partial = ready_file + ".partial"
            with open(partial, "w") as f:
                f.write(server.robot_servers[0].hostname)
            os.replace(partial, ready_file)
            server.run_forever()


if __name__ == "__main__":
    main()
