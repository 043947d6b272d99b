"""Benchmark rows of the robot loop (``scenarios.run``).

``loop.sim_paced.p99``: cycle time (read returned -> command written, us) of the controller and
the sim backend in a paced 1 kHz run (approach, impact, retract; goal p99 <= 500 us).
``loop.period_jitter.p99``: |interval between consecutive cycle starts - period| (us) of that run.
``impact.detection_latency``: ms from the contact start (first force sample above 1 N) to the
online detection, over a short campaign of unpaced simulated approaches (goal <= 5 ms).
The overrun watchdog is off in these runs (they measure, they do not protect).
"""

from __future__ import annotations

import numpy as np

from impactqp.controller.model.postures import POSTURES
from impactqp.scenarios.run import SIM_START_DISTANCE, RunRequest, run

NO_OVERRUN_TRIP = 10**9
CAMPAIGN_SPEEDS = (0.1, 0.15)


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
    for posture in POSTURES:
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
