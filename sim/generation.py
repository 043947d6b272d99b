"""Datasets generated in simulation, in the format of a real robot log (``controller.measured.dataset``).

Each trial is an approach-and-impact of :func:`sim.runner.run_approach`: the contact point
starts ``START_DISTANCE`` in front of the surface, already moving at the reference velocity
(:class:`sim.trial_sources.CartesianApproachCommand`, the kinematic control of the paper's
experiments), hits the surface and keeps commanding the approach for ``AFTER_CONTACT`` s.

Trials: every posture x every normal speed, then every posture x every tangential speed at the
normal speed ``TANGENTIAL_SERIES_NORMAL_SPEED`` (the paper's second series, 0.12 m/s). The
tangential velocity is ``speed * t`` with ``t = normalise(n x e_z)`` (for the default wall,
n = -x, t = +y: the paper's v_y), or ``normalise(n x e_x)`` when n is vertical.

What a real log holds, simulated: encoder-like Gaussian noise on dq (std ``noise_dq``, default
0.0042 rad/s, the paper's repeat-to-repeat std) and on tau (``noise_tau``), and the plant's
quantisation of dq (``sensor_velocity_step``: ``sim.sensor.quantised_velocity``, after the noise,
an encoder-based velocity; the manifest then declares that ``encoder_step``); repeat-to-repeat
variation of the start posture (Gaussian, std 0.000954 rad, the paper's std of q) and of the
start distance (+-1 mm). The force log (on the robot, world frame, physics rate) is kept
noise-free. A plant with sensor keys (``sim.sensor``: delay, velocity scale and filter, torque
offset) logs dq and tau through that faulty sensor before the noise is added: a dataset of a
sensor fault. A **per-trial variable delay** (``DatasetRequest.velocity_delays`` = m) logs each
trial's dq d whole samples late, d drawn per trial, uniformly in 0..m, from the trial's seed
(``sim.sensor.delayed``; tau on time): a log whose timing goes wrong by a different amount in
every trial, which no sensor cause (one delay for the whole dataset, on dq and tau) holds. The
plant parameters and the delays that produced the data are never written.

One header for every simulated dataset (:func:`dataset_header`: the robot and the tool, the
surface, the 1 ms control period). The standing robot's simulated trials (``sim.runner.run_impact_trial``,
what ``simulate --robot g1 --out DIR`` and ``campaign --robot g1`` write) are written in the
simulation's world frame moved along x onto the wall plane: the wall is :data:`STANDING_WALL`,
through the origin with normal (-1, 0, 0), whatever the stance (each stance puts its wall 2 cm,
with the whole-body QP 5 cm, in front of its hand), so that the trials of every stance and command
source share one manifest. A real humanoid's state estimator has its own origin too; only the base
position's x column depends on the choice. The trial's ``TrialResult.log`` holds the rows (the
servo's torque of row k held over [t_k, t_k+1), the wall force per physics step); its first
contact is the manifest's ``impact_time`` (``TrialResult.dataset_trial``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import DatasetHeader, TrialEntry
from impactqp.controller.measured.dataset_writer import DatasetWriter, check_room, trial_bytes
from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot_description import ROBOTS, RobotDescription
from impactqp.controller.model.validation import (
    MAX_TRIALS,
    BadInputError,
    counted,
    number_in_range,
    simulated_speed,
    tangential_speed,
    trial_count,
    whole_number,
)

from .plant import PlantParameters
from .process_pool import ProcessPool
from .runner import DEFAULT_CONTROL_PERIOD, NORMAL, TrialSpec, run_approach
from .scene import DEFAULT_TIMESTEP, WALL_FRICTION, build_scene
from .sensor import apply_sensor, delayed, quantised_velocity

DEFAULT_SPEEDS = (0.08, 0.10, 0.12, 0.15, 0.18)
TANGENTIAL_SERIES_NORMAL_SPEED = 0.12
DEFAULT_NOISE_DQ = 0.0042
DEFAULT_NOISE_TAU = 0.05
START_POSTURE_STD = 0.000954
START_DISTANCE = 0.02
START_DISTANCE_SPREAD = 0.001
AFTER_CONTACT = 0.05
MAX_REPEATS = 100
"""Repeats per condition: the paper repeats each impact a handful of times; 100 bounds the run."""
MAX_NOISE_DQ, MAX_NOISE_TAU = 1.0, 10.0
"""rad/s and N m: noise far above a Panda's encoders (~0.004 rad/s) and torque sensors (~0.05 N m)."""
MAX_VELOCITY_DELAY = 50
"""Control periods: the most samples a per-trial variable delay of dq may draw (``sensor_delay``'s bound)."""
STANDING_WALL = Surface(np.zeros(3), NORMAL, WALL_FRICTION)
"""The wall of the standing robot's datasets (module docstring)."""


def dataset_header(
    surface: Surface, choice: RobotChoice = DEFAULT_CHOICE, plant: PlantParameters | None = None
) -> DatasetHeader:
    """The manifest header of a simulated dataset: the robot and the tool of ``choice``, the
    surface, the trial loop's control period, and the encoder step of dq when ``plant``'s
    sensor quantises it (``sensor_velocity_step``)."""
    header = DatasetHeader.of(choice, surface, DEFAULT_CONTROL_PERIOD)
    steps = () if plant is None else plant.for_joints(len(choice.robot.joints)).sensor_velocity_step
    return replace(header, encoder_step=tuple(steps)) if any(s > 0.0 for s in steps) else header


def tangential_direction(normal: np.ndarray) -> np.ndarray:
    """The documented tangential direction t of the surface plane (module docstring)."""
    axis = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t = np.cross(normal, axis)
    return t / np.linalg.norm(t)


@dataclass(frozen=True)
class PlannedTrial:
    """A trial of the dataset to generate: its id, its noise seed, and the nominal trial."""

    id: str
    seed: int
    spec: TrialSpec


def trial_specs(
    postures: list[str], speeds: list[float], tangential: list[float], repeats: int, normal: np.ndarray, seed: int,
    choice: RobotChoice = DEFAULT_CHOICE,
) -> list[PlannedTrial]:
    whole_number(repeats, 1, MAX_REPEATS, "repeats")
    whole_number(seed, 0, None, "the seed --seed")
    for v in speeds:
        simulated_speed(v, "every normal speed")
    for v in tangential:
        tangential_speed(v, "every tangential speed")
    t = tangential_direction(normal)
    conditions = [(p, v, np.zeros(3)) for p in postures for v in speeds]
    conditions += [(p, TANGENTIAL_SERIES_NORMAL_SPEED, vt * t) for p in postures for vt in tangential]
    seeds = np.random.SeedSequence(seed).generate_state(len(conditions) * repeats)
    planned = []
    for c, (posture, v, vt) in enumerate(conditions):
        spec = TrialSpec(
            posture, choice.posture(posture).q, float(v), vt, start_distance=START_DISTANCE, after_contact=AFTER_CONTACT
        )
        for r in range(repeats):
            index = c * repeats + r
            planned.append(PlannedTrial(f"t{index:04d}", int(seeds[index]), spec))
    return planned


@dataclass(frozen=True)
class TrialTask:
    """One trial to simulate (a process task): the planned trial, the plant and surface, the
    noise stds on dq (rad/s) and tau (N m), the robot and the tool, and the most samples its dq
    may be logged late (``DatasetRequest.velocity_delays``)."""

    planned: PlannedTrial
    plant: PlantParameters
    surface: Surface
    noise_dq: float
    noise_tau: float
    choice: RobotChoice = DEFAULT_CHOICE
    velocity_delays: int = 0


def simulate_trial(task: TrialTask) -> tuple[TrialEntry, TrialLog]:
    """Run one trial from a randomly perturbed start, log dq late by the trial's drawn delay
    (none unless ``task.velocity_delays``) and add the measurement noise; returns (entry, log)."""
    planned = task.planned
    rng = np.random.default_rng(planned.seed)
    robot = task.choice.model()
    scene = build_scene(task.surface, task.plant.physical(), robot=task.choice.robot, tool=task.choice.tool)
    spec = planned.spec
    q_contact = np.clip(spec.q_contact + rng.normal(0.0, START_POSTURE_STD, robot.nq), robot.q_min, robot.q_max)
    distance = spec.start_distance + rng.uniform(-START_DISTANCE_SPREAD, START_DISTANCE_SPREAD)
    log = run_approach(scene, robot, replace(spec, q_contact=q_contact, start_distance=distance)).log
    log = apply_sensor(log, task.plant, log.control_period)
    noise_dq = rng.normal(0.0, task.noise_dq, log.dq.shape)
    noise_tau = rng.normal(0.0, task.noise_tau, log.tau.shape)
    delay = int(rng.integers(0, task.velocity_delays + 1)) if task.velocity_delays else 0
    log.dq = delayed(np.asarray(log.dq, float), delay) + noise_dq
    log.tau = log.tau + noise_tau
    log.dq = quantised_velocity(log.dq, task.plant, robot.nv)
    entry = TrialEntry(
        id=planned.id,
        file=f"{planned.id}.csv",
        reference_normal_speed=spec.normal_speed,
        force_file=f"{planned.id}_force.csv",
        reference_tangential_velocity=tuple(spec.tangential_velocity.tolist()),
        posture=spec.posture,
    )
    return entry, log


def dataset_bytes(specs: Sequence[TrialSpec], robot: RobotDescription) -> float:
    """The estimated size of a dataset of the trials ``specs``, before any runs (for
    ``dataset_writer.check_room``): each trial's nominal duration (its start distance at its
    normal speed, then ``after_contact``) in control samples for its trial file and in physics
    steps (``DEFAULT_TIMESTEP``) for its force file."""
    total = 0.0
    for spec in specs:
        duration = spec.start_distance / spec.normal_speed + spec.after_contact
        total += trial_bytes(robot, round(duration / DEFAULT_CONTROL_PERIOD), round(duration / DEFAULT_TIMESTEP))
    return total


@dataclass(frozen=True)
class DatasetRequest:
    """What dataset to simulate: the plant that makes it (nominal by default), the surface (by
    default the one the first posture faces; all named postures face the default wall), the
    postures (default: all), normal speeds (m/s, default ``DEFAULT_SPEEDS``), tangential speeds
    (m/s, at ``TANGENTIAL_SERIES_NORMAL_SPEED``), repeats per condition, the noise stds, the
    seed of every random draw, the robot and the tool (recorded in the manifest), the most
    trials it may hold (``validation.trial_count``), and the per-trial variable delay: each
    trial's dq logged 0..``velocity_delays`` whole samples late (module docstring; 0: none)."""

    plant: PlantParameters | None = None
    surface: Surface | None = None
    postures: Sequence[str] | None = None
    speeds: Sequence[float] | None = None
    tangential: Sequence[float] = ()
    repeats: int = 1
    noise_dq: float = DEFAULT_NOISE_DQ
    noise_tau: float = DEFAULT_NOISE_TAU
    seed: int = 0
    choice: RobotChoice = DEFAULT_CHOICE
    max_trials: int = MAX_TRIALS
    velocity_delays: int = 0


def generate_dataset(
    out: str | Path,
    request: DatasetRequest = DatasetRequest(),
    *,
    jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> list[TrialEntry]:
    """Simulate the trials of ``request`` on ``jobs`` processes and write them to ``out``
    (created if missing) as they finish, in order; returns the entries.

    ``progress(done, total)`` is an optional callable invoked once per finished trial.
    """
    plant = request.plant or PlantParameters()
    choice = request.choice
    postures = list(choice.robot.postures) if request.postures is None else list(request.postures)
    if not postures:
        raise BadInputError(f"give at least one posture; known: {', '.join(choice.robot.postures)}")
    choice.check_postures(postures)
    surface = choice.posture(postures[0]).surface if request.surface is None else request.surface
    number_in_range(request.noise_dq, 0.0, MAX_NOISE_DQ, "the encoder noise std --noise-dq", "rad/s")
    number_in_range(request.noise_tau, 0.0, MAX_NOISE_TAU, "the torque noise std --noise-tau", "N m")
    speeds = list(DEFAULT_SPEEDS if request.speeds is None else request.speeds)
    whole_number(request.repeats, 1, MAX_REPEATS, "repeats")
    whole_number(request.velocity_delays, 0, MAX_VELOCITY_DELAY, "the per-trial delay of dq (samples)")
    trial_count(
        len(postures) * (len(speeds) + len(request.tangential)) * request.repeats, request.max_trials, "the dataset",
        f"{counted(len(postures), 'posture')} x ({counted(len(speeds), 'speed')} + {len(request.tangential)} tangential)"
        f" x {counted(request.repeats, 'repeat')}",
    )
    specs = trial_specs(
        postures,
        speeds,
        list(request.tangential or []),
        request.repeats,
        surface.normal,
        request.seed,
        choice,
    )
    check_room(out, dataset_bytes([planned.spec for planned in specs], choice.robot), f"the {counted(len(specs), 'trial')}")
    Path(out).mkdir(parents=True, exist_ok=True)
    writer = DatasetWriter(out, dataset_header(surface, choice, plant), expected_trials=len(specs))
    tasks = [TrialTask(s, plant, surface, request.noise_dq, request.noise_tau, choice, request.velocity_delays)
             for s in specs]
    entries = []
    with ProcessPool(min(jobs, max(len(tasks), 1))) as pool:
        for entry, log in pool.map(simulate_trial, tasks):
            writer.add_trial(entry, log)
            entries.append(entry)
            if progress:
                progress(len(entries), len(tasks))
    return entries


# ---------------------------------------------------------------------------- the standing robot's trials
def open_dataset(directory: str | Path, robot: RobotDescription = ROBOTS["g1"]) -> DatasetWriter:
    """The writer of the dataset of ``robot``'s trials in ``directory`` (created with the first
    trial); an existing dataset of another header is refused here, before any trial is simulated."""
    return DatasetWriter(directory, dataset_header(STANDING_WALL, RobotChoice(robot)))


def write_trials(writer: DatasetWriter, trials) -> list[TrialEntry]:
    """Add ``trials`` (``sim.trial_result.TrialResult``) to the dataset of ``writer`` (``open_dataset``); a trial of
    an id the dataset holds with other data is refused, the same trial again changes nothing."""
    entries = []
    for trial in trials:
        entry, log = trial.dataset_trial()
        writer.add_trial(entry, log)
        entries.append(entry)
    return entries
