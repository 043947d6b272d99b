"""Benchmark rows of the robot loop (``scenarios.run``).

``loop.sim_paced.p99``: cycle time (read returned -> command written, us) of the controller and
the sim backend in a paced 1 kHz run (approach, impact, retract; goal p99 <= 500 us).
``loop.period_jitter.p99``: |interval between consecutive cycle starts - period| (us) of that run.
``impact.detection_latency``: ms from the contact start (first force sample above 1 N) to the
online detection, over a short campaign of unpaced simulated approaches (goal <= 5 ms).
``loop.franka_sim.p99``: cycle time (us, in our process) of ``impactqp run --backend franka``
through pylibfranka and the real network protocol against franky-sim (an FR3 in MuJoCo, with the
wall and the tool in its scene); ``impact.detection_latency.franka_sim``: ms from the server's
first wall contact to our detection in that run, both on the states' clock (the server runs in
lockstep with the loop, ``sim.franky_sim``: 0 is a detection at the first state after the
contact). They need the ``franka`` and ``test`` extras and are left out without them.
The overrun watchdog is off in these runs (they measure, they do not protect).
"""

from __future__ import annotations

import functools
import importlib.util
import tempfile
from pathlib import Path

import numpy as np

from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.scenarios.run import SIM_START_DISTANCE, RunRequest, run
from impactqp.sim.franky_sim import FrankySimServer

NO_OVERRUN_TRIP = 10**9
CAMPAIGN_SPEEDS = (0.1, 0.15)
FRANKA_SIM_POSTURE = "elbow_up"
FRANKA_SIM_ROBOT = "fr3"  # franky-sim serves an FR3


def rows(duration: float = 1.0) -> list[dict]:
    _, result = run(RunRequest(speed=0.15, duration=duration, unpaced=False, max_overruns=NO_OVERRUN_TRIP))
    stats = result.cycle_us
    jitter = result.period_error_us
    return [
        {"name": "loop.sim_paced.p99", "unit": "us", "median": stats["p50"], "p99": stats["p99"]},
        {
            "name": "loop.period_jitter.p99",
            "unit": "us",
            "median": float(np.median(jitter)),
            "p99": float(np.percentile(jitter, 99)),
        },
    ]


def detection_rows() -> list[dict]:
    latencies = []
    for posture in PANDA.postures:
        for speed in CAMPAIGN_SPEEDS:
            duration = SIM_START_DISTANCE / speed + 0.1  # from rest: the contact comes after the nominal time
            report, _ = run(RunRequest(posture=posture, speed=speed, duration=duration, unpaced=True))
            latency = report["impact"]["detection_latency_ms"]
            latencies.append(np.inf if latency is None else latency)
    return [
        {
            "name": "impact.detection_latency",
            "unit": "ms",
            "median": float(np.median(latencies)),
            "p99": float(np.percentile(latencies, 99)),
        }
    ]


@functools.cache
def franka_sim_run() -> tuple[dict, float | None] | None:
    """(report, the server's contact time) of one session against franky-sim, started at the
    posture's start; None without pylibfranka or franky-sim."""
    if importlib.util.find_spec("pylibfranka") is None or importlib.util.find_spec("franky_sim") is None:
        return None
    posture = ROBOTS[FRANKA_SIM_ROBOT].postures[FRANKA_SIM_POSTURE]
    q0 = approach_start(RobotModel(FRANKA_SIM_ROBOT), posture.q, posture.surface, SIM_START_DISTANCE)
    with tempfile.TemporaryDirectory() as directory:
        with FrankySimServer(Path(directory) / "server", posture.surface.point, posture.surface.normal, q0) as server:
            request = RunRequest(
                backend="franka", choice=RobotChoice.of(FRANKA_SIM_ROBOT, "impact_tip"), robot_ip=server.hostname,
                realtime=False,
                posture=FRANKA_SIM_POSTURE, duration=1.0, max_overruns=NO_OVERRUN_TRIP,
            )
            report, _ = run(request)
            return report, server.contact_time()


def franka_sim_loop_rows() -> list[dict]:
    outcome = franka_sim_run()
    if outcome is None:
        return []
    stats = outcome[0]["cycle_us"]
    return [{"name": "loop.franka_sim.p99", "unit": "us", "median": stats["p50"], "p99": stats["p99"]}]


def franka_sim_detection_rows() -> list[dict]:
    outcome = franka_sim_run()
    if outcome is None:
        return []
    report, t_contact = outcome
    t_detect = report["impact"]["time"]
    latency = np.inf if t_detect is None or t_contact is None else (t_detect - t_contact) * 1e3
    return [{"name": "impact.detection_latency.franka_sim", "unit": "ms", "median": latency, "p99": latency}]
