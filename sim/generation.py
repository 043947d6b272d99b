"""Datasets generated in simulation, in the format of a real robot log (``controller.measured.dataset``).

Each trial is an approach-and-impact of :func:`sim.runner.run_approach_trial`: the contact point
starts ``START_DISTANCE`` in front of the surface, already moving at the reference velocity
(:class:`sim.runner.CartesianApproachCommand`, the kinematic control of the paper's
experiments), hits the surface and keeps commanding the approach for ``AFTER_CONTACT`` s.

Trials: every posture x every normal speed, then every posture x every tangential speed at the
normal speed ``TANGENTIAL_SERIES_NORMAL_SPEED`` (the paper's second series, 0.12 m/s). The
tangential velocity is ``speed * t`` with ``t = normalise(n x e_z)`` (for the default wall,
n = -x, t = +y: the paper's v_y), or ``normalise(n x e_x)`` when n is vertical.

What a real log holds, simulated: encoder-like Gaussian noise on dq (std ``noise_dq``, default
0.0042 rad/s, the paper's repeat-to-repeat std) and on tau (``noise_tau``); repeat-to-repeat
variation of the start posture (Gaussian, std 0.000954 rad, the paper's std of q) and of the
start distance (+-1 mm). The force log (on the robot, world frame, physics rate) is kept
noise-free. The plant parameters that produced the data are never written.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from impactqp.controller.model.postures import POSTURES, Surface
from impactqp.controller.model.robot import NQ, PandaModel

from impactqp.controller.measured.dataset import DatasetWriter, TrialEntry
from .plant import PlantParameters
from .runner import dataset_header, run_approach_trial
from .scene import build_scene
from impactqp.controller.model.validation import BadInputError, approach_speed

DEFAULT_SPEEDS = (0.08, 0.10, 0.12, 0.15, 0.18)
TANGENTIAL_SERIES_NORMAL_SPEED = 0.12
DEFAULT_NOISE_DQ = 0.0042
DEFAULT_NOISE_TAU = 0.05
START_POSTURE_STD = 0.000954
START_DISTANCE = 0.02
START_DISTANCE_SPREAD = 0.001
AFTER_CONTACT = 0.05


def tangential_direction(normal: np.ndarray) -> np.ndarray:
    """The documented tangential direction t of the surface plane (module docstring)."""
    axis = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t = np.cross(normal, axis)
    return t / np.linalg.norm(t)


@dataclass(frozen=True)
class TrialSpec:
    id: str
    posture: str
    normal_speed: float
    tangential_velocity: tuple[float, float, float]
    seed: int


def trial_specs(
    postures: list[str], speeds: list[float], tangential: list[float], repeats: int, normal: np.ndarray, seed: int
) -> list[TrialSpec]:
    for v in speeds:
        approach_speed(v, "every normal speed")
    for v in tangential:
        approach_speed(abs(v) if v else 1.0, "every tangential speed")
    if repeats < 1:
        raise BadInputError("repeats must be >= 1")
    t = tangential_direction(normal)
    conditions = [(p, v, np.zeros(3)) for p in postures for v in speeds]
    conditions += [(p, TANGENTIAL_SERIES_NORMAL_SPEED, vt * t) for p in postures for vt in tangential]
    seeds = np.random.SeedSequence(seed).generate_state(len(conditions) * repeats)
    specs = []
    for c, (posture, v, vt) in enumerate(conditions):
        for r in range(repeats):
            index = c * repeats + r
            specs.append(TrialSpec(f"t{index:04d}", posture, float(v), tuple(vt.tolist()), int(seeds[index])))
    return specs


def simulate_trial(spec: TrialSpec, plant: PlantParameters, surface: Surface, noise_dq: float, noise_tau: float):
    """Run one trial and add the measurement noise; returns (entry, log)."""
    rng = np.random.default_rng(spec.seed)
    robot = PandaModel()
    scene = build_scene(surface, plant)
    q_contact = POSTURES[spec.posture].q + rng.normal(0.0, START_POSTURE_STD, NQ)
    q_contact = np.clip(q_contact, robot.q_min, robot.q_max)
    distance = START_DISTANCE + rng.uniform(-START_DISTANCE_SPREAD, START_DISTANCE_SPREAD)
    log = run_approach_trial(
        scene,
        robot,
        q_contact,
        spec.normal_speed,
        tangential_velocity=np.array(spec.tangential_velocity),
        start_distance=distance,
        after_contact=AFTER_CONTACT,
    )
    log.dq = log.dq + rng.normal(0.0, noise_dq, log.dq.shape)
    log.tau = log.tau + rng.normal(0.0, noise_tau, log.tau.shape)
    entry = TrialEntry(
        id=spec.id,
        file=f"{spec.id}.csv",
        reference_normal_speed=spec.normal_speed,
        force_file=f"{spec.id}_force.csv",
        reference_tangential_velocity=spec.tangential_velocity,
        posture=spec.posture,
    )
    return entry, log


def generate_dataset(
    out: str | Path,
    *,
    plant: PlantParameters | None = None,
    surface: Surface | None = None,
    postures: list[str] | None = None,
    speeds: list[float] | None = None,
    tangential: list[float] | None = None,
    repeats: int = 1,
    noise_dq: float = DEFAULT_NOISE_DQ,
    noise_tau: float = DEFAULT_NOISE_TAU,
    seed: int = 0,
    jobs: int = 1,
    progress=None,
) -> list[TrialEntry]:
    """Simulate the trials and write them to ``out`` (created if missing); returns the entries.

    The surface defaults to the one the first posture faces (all named postures face the
    default wall).
    ``progress(done, total)`` is an optional callable invoked once per finished trial.
    """
    plant = plant or PlantParameters()
    postures = list(POSTURES) if postures is None else postures
    unknown = [p for p in postures if p not in POSTURES]
    if unknown or not postures:
        raise BadInputError(f"unknown posture(s) {', '.join(unknown)}; known: {', '.join(POSTURES)}")
    surface = POSTURES[postures[0]].surface if surface is None else surface
    if not (np.isfinite(noise_dq) and noise_dq >= 0 and np.isfinite(noise_tau) and noise_tau >= 0):
        raise BadInputError("noise standard deviations must be finite and >= 0")
    specs = trial_specs(
        postures,
        list(DEFAULT_SPEEDS if speeds is None else speeds),
        list(tangential or []),
        repeats,
        surface.normal,
        seed,
    )
    Path(out).mkdir(parents=True, exist_ok=True)
    writer = DatasetWriter(out, dataset_header(surface))
    args = [(s, plant, surface, noise_dq, noise_tau) for s in specs]
    entries = []
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as pool:
            results = pool.map(simulate_trial, *zip(*args))
            for entry, log in results:
                writer.add_trial(entry, log)
                entries.append(entry)
                if progress:
                    progress(len(entries), len(specs))
    else:
        for a in args:
            entry, log = simulate_trial(*a)
            writer.add_trial(entry, log)
            entries.append(entry)
            if progress:
                progress(len(entries), len(specs))
    return entries
