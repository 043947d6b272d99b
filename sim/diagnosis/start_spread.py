"""How far a replay's own start moves what it is compared with: the start spread of each residual
(``start_spread``), the residuals' share of the fit test that no cause can remove.

A replay starts from the logged state ``REPLAY_LEAD`` samples before the impact, its velocity
the mean of ``START_SAMPLES`` noisy samples (``trials``): it starts off the robot's true velocity
by an error of std sigma_j / sqrt(START_SAMPLES) per joint j (sigma_j^2 the trial's per-sample
scatter of dq, ``MeasuredTrial.scatter``). Every compared feature carries that error through the
replay. Where the replay is smooth in its start, the error is a fraction of the sensor noise; where
it is not, it can be many noise units: a tool that slides across the wall and whose slip ends
inside the impact moves its joint jumps by tens of noise units when the start velocity moves by
its own std (``docs/diagnosis.md``, "The replay's start spread").

The spread of residual i (in noise units, ``fitting.residual_blocks``) at a plant is the first-order
std of that error, by central differences over the joints:

    s_i^2 = sum_j ((r_i(dq0 + d_j e_j) - r_i(dq0 - d_j e_j)) / 2)^2,   d_j = sigma_j / sqrt(START_SAMPLES),

two replays per joint and trial (the trials split over the diagnosis's processes). Before the
contact (the torque) the replay is smooth in its start and s_i is its first-order std; what the
contact follows is only piecewise smooth (the replay touches the wall at one of its physics steps),
and there s_i is a secant over one std of the start error, which also catches a kink within that
std. The noise model's own terms (``noise``) already hold a start error of the usual size (the
torque's ``REPLAY_TORQUE_FACTOR``, the trace's timing term: a right model reads 1 to 2 noise units,
and the limits of the fit test are set on that), so a residual's std becomes max(1, s_i) noise units
(``fitting.residual_blocks`` with a spread): it grows only where the replay is more sensitive to its
start than the noise itself, never below the calibrated noise. A perturbed replay that is unstable
adds nothing (its joint's difference is not a start error).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from impactqp.sim.plant import PlantParameters
from impactqp.sim.process_pool import map_in_processes
from impactqp.sim.sensor import apply_sensor

from .fitting import residual_blocks
from .trials import START_AVERAGE, MeasuredTrial, ReplaySetting, replay, simulated_log

START_SAMPLES = 2 * START_AVERAGE + 1
"""The logged samples averaged into a replay's start velocity (``trials.START_AVERAGE``)."""


@dataclass(frozen=True)
class SpreadTask:
    """The start spreads of some trials replayed in one plant (a process task)."""

    setting: ReplaySetting
    plant: PlantParameters
    trials: tuple[MeasuredTrial, ...]


def start_spread(setting: ReplaySetting, plant: PlantParameters, trials: list[MeasuredTrial], jobs: int = 1) -> list[dict]:
    """Per trial, the start spread of every residual block (``fitting.residual_blocks``: block ->
    array of s_i, noise units; module docstring) of the replays of ``trials`` in ``plant``, the
    trials split into ``jobs`` runs of consecutive trials, each on its own process."""
    chunks = [tuple(chunk) for chunk in np.array_split(np.arange(len(trials)), max(min(jobs, len(trials)), 1))]
    tasks = [SpreadTask(setting, plant, tuple(trials[k] for k in chunk)) for chunk in chunks]
    return [spread for spreads in map_in_processes(trial_spreads, tasks, len(tasks)) for spread in spreads]


def trial_spreads(task: SpreadTask) -> list[dict]:
    """The start spread of each of ``task``'s trials (``start_spread``), one scene for all."""
    setting, plant = task.setting, task.plant
    scene = []

    def scene_of():
        if not scene:
            scene.append(setting.scene(plant.physical()))
        return scene[0]

    def blocks_from(trial: MeasuredTrial, dq0: np.ndarray) -> dict | None:
        log = simulated_log(setting, plant, replace(trial, dq0=dq0), scene_of)
        if log is None:
            return None
        return residual_blocks(replay(apply_sensor(log, plant, trial.control_period), trial), trial)

    spreads = []
    for trial in task.trials:
        steps = np.sqrt(np.asarray(trial.scatter[0], float) / START_SAMPLES)
        squares: dict = {}
        for j in np.flatnonzero(steps > 0.0):
            step = np.zeros_like(trial.dq0)
            step[j] = steps[j]
            plus, minus = blocks_from(trial, trial.dq0 + step), blocks_from(trial, trial.dq0 - step)
            if plus is None or minus is None:
                continue
            for name in plus:
                squares[name] = squares.get(name, 0.0) + (0.5 * (plus[name] - minus[name])) ** 2
        spreads.append({name: np.sqrt(value) for name, value in squares.items()})
    return spreads
