"""The diagnosis's trials: load the valid ones of a dataset, replay them in the simulation.

1. **Measure** (``load_trials``). Every trial of the dataset is checked
   (``controller.measured.dataset_check.validate``); bad trials are skipped with their reasons. The
   impact is detected and the jump extracted with the same function as for simulated data
   (``controller.measured.impact.measure_impact``); the impulse is integrated where a force log
   exists. The noise of every compared signal is read from the trials (``noise``), with the
   encoders' quantisation steps (``encoder_steps``).
2. **Replay** (``replay``). Each trial is replayed in the simulation from the logged state
   ``REPLAY_LEAD`` control steps before the impact (q, and dq averaged over 5 samples against
   encoder noise), on the dataset's surface, with the logged ``dq_cmd`` driving the joint servo,
   until ``REPLAY_TAIL`` steps after the detection. The servo's reference at that sample is
   rebuilt from the log start and the commands before it (``servo_reference_from_commands``), so
   a plant that lags behind its commands (joint damping) lags in the replay as it did. The
   replayed impact is measured with the same function. Jumps are compared at fixed samples per
   trial (``locate_jump_samples``). The plant's sensor keys (``sim.sensor``) act on the replayed
   log after the simulation; the simulated logs of the last ``REPLAY_CACHE_SIZE`` replays are
   kept per process, keyed by the physical plant and the trial, so causes that only change the
   sensor (and fits on top of a fixed physical plant) need no new simulation.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from impactqp.controller.measured.dataset import read_dataset
from impactqp.controller.measured.dataset_check import validate
from impactqp.controller.measured.impact import (
    POST_HALF_WIDTH,
    PRE_SAMPLES,
    ImpactNotFoundError,
    measure_impact,
)
from impactqp.controller.model.choice import DEFAULT_CHOICE, RobotChoice
from impactqp.controller.model.postures import Surface

from impactqp.sim.plant import PlantParameters
from impactqp.sim.runner import SimulationUnstableError, run_trial, servo_reference_from_commands
from impactqp.sim.trial_sources import CommandReplay
from impactqp.sim.scene import Scene, build_scene
from impactqp.sim.sensor import apply_sensor, delayed, velocity_scales

from .noise import BlockNoise, estimate_noise, quantisation_step, sample_variance

REPLAY_LEAD = 40
REPLAY_TAIL = 30
START_AVERAGE = 2  # dq at the replay start: mean of samples i0 - 2 .. i0 + 2 (within the log)
TORQUE_SETTLE = 10  # samples after the replay start before the torque window may begin
TORQUE_WINDOW = 30  # mean tau over the 30 samples ending 2 samples before the pre-impact one
TRACE_LENGTH = 16  # samples of the impact trace after the pre-impact one: the jump's rise (soft contact ~10 ms)
REPLAY_CACHE_SIZE = 2048  # a 70-sample log holds about 30 kB: 60 MB at most per process
_simulated: OrderedDict = OrderedDict()  # (surface, physical plant, trial) -> simulated log or None


@dataclass
class MeasuredTrial:
    """What the diagnosis needs of one valid trial."""

    id: str
    posture: str | None
    reference_speed: float
    tangential_speed: float
    q0: np.ndarray
    dq0: np.ndarray
    servo_reference: tuple[np.ndarray, np.ndarray]
    dq_cmd: np.ndarray
    control_period: float
    jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None
    torque: np.ndarray
    q_pre: np.ndarray
    dq_pre: np.ndarray
    torque_window: tuple[int, int]  # samples of the replay whose torque is averaged
    dq_log: np.ndarray  # the measured dq over the replay's span (replay sample k is dq_log[k])
    tau_log: np.ndarray  # the measured tau over the same span
    jump_samples: tuple[int, int]  # replay samples (pre, post) where the fit reads the jumps
    scatter: tuple[np.ndarray, np.ndarray]  # per-sample noise variance of dq and tau before the impact
    force_period: float | None  # the force log's sample period (s), None without force data
    noise: BlockNoise | None = None  # the dataset's block noise (``noise.estimate_noise``)

    @property
    def reference(self) -> np.ndarray:
        """The measured jump read at ``jump_samples`` (``jump_at``): what the fit compares."""
        return jump_at(self.dq_log, *self.jump_samples)

    @property
    def reference_trace(self) -> np.ndarray:
        """The measured trace of the impact (``impact_trace``): what the fit compares."""
        return impact_trace(self.dq_log, self.tau_log, self.jump_samples[0])


def jump_at(dq: np.ndarray, pre: int, post: int) -> np.ndarray:
    """The jump of the velocities ``dq`` read at the samples (pre, post) with the averages of
    ``controller.measured.impact``: the mean of 2 h + 1 samples about ``post`` minus the mean of
    the ``PRE_SAMPLES`` ending at ``pre``."""
    dq_pre = dq[pre - PRE_SAMPLES + 1 : pre + 1].mean(axis=0)
    return dq[post - POST_HALF_WIDTH : post + POST_HALF_WIDTH + 1].mean(axis=0) - dq_pre


def trace_at(x: np.ndarray, pre: int) -> np.ndarray:
    """(TRACE_LENGTH, columns): the samples of ``x`` in the TRACE_LENGTH after ``pre`` minus
    the mean of the ``PRE_SAMPLES`` ending at ``pre``: how the signal changes through the
    impact, sample by sample."""
    x_pre = x[pre - PRE_SAMPLES + 1 : pre + 1].mean(axis=0)
    return x[pre + 1 : pre + 1 + TRACE_LENGTH] - x_pre


def impact_trace(dq: np.ndarray, tau: np.ndarray, pre: int) -> np.ndarray:
    """(TRACE_LENGTH, 2 x joints): the traces (``trace_at``) of the joint velocities (the first
    columns) and torques (the last). A jump read at two samples cannot tell a late sensor from a filtered
    velocity or from a plant that yields slowly: the velocity's rise and the torque's answer,
    sample by sample, can (a late sensor moves both, a velocity filter only rounds the
    first; ``docs/diagnosis.md``)."""
    return np.hstack([trace_at(dq, pre), trace_at(tau, pre)])


@dataclass(frozen=True)
class ReplayFeatures:
    """What a replay gives: its jump read at the trial's ``jump_samples`` (compared with the
    trial's ``reference``), its impulse, contact duration and pre-impact torque, its jump
    as ``controller.measured.impact`` detects and reads it (for the report) and its impact
    trace (``impact_trace``, compared with the trial's ``reference_trace``)."""

    jump: np.ndarray
    impulse: np.ndarray | None
    duration: float | None
    torque: np.ndarray
    detected_jump: np.ndarray
    trace: np.ndarray


@dataclass(frozen=True)
class ReplaySetting:
    """What the trials were taken on and with: the surface hit, and the robot and the tool that
    hit it (the dataset manifest's ``robot`` and ``tool``). Every replay simulates them and every
    prediction uses their model."""

    surface: Surface
    choice: RobotChoice = DEFAULT_CHOICE

    def scene(self, plant: PlantParameters) -> Scene:
        """The MuJoCo scene of the setting with the plant ``plant``."""
        return build_scene(self.surface, plant, robot=self.choice.robot, tool=self.choice.tool)


def load_trials(directory: str | Path) -> tuple[list[MeasuredTrial], list[dict], ReplaySetting]:
    """Valid trials ready for replay, the skipped ones with their reasons, and the setting of
    the manifest (its surface, robot and tool: any declared tool)."""
    directory = Path(directory)
    problems = validate(directory)
    bad = {k for k, v in problems.items() if k != "dataset" and v}
    dataset = read_dataset(directory, skip=bad, strict=False)
    skipped = [{"id": k, "reason": "; ".join(problems[k])} for k in sorted(bad)]
    skipped += [{"id": "dataset", "reason": p} for p in problems["dataset"]]
    trials = []
    period = dataset.header.control_period
    dq_step, tau_step = encoder_steps(dataset)
    for trial in dataset.trials:
        log, entry = trial.log, trial.entry
        try:
            impact = measure_impact(log)
        except ImpactNotFoundError as error:
            skipped.append({"id": entry.id, "reason": f"no impact found: {error}"})
            continue
        i0 = max(impact.pre_index - REPLAY_LEAD, 0)
        i1 = impact.detect_index + REPLAY_TAIL
        last = impact.pre_index - 2
        first = max(i0 + TORQUE_SETTLE, last - TORQUE_WINDOW)
        if last - first < 3 or i1 > len(log):
            skipped.append({"id": entry.id, "reason": "too short around the impact for a replay"})
            continue
        if i1 < len(log):
            # impulse and contact duration over the span that the replay covers
            impact = measure_impact(log.truncated(log.t[i1]))
        tangential = entry.reference_tangential_velocity
        quiet = impact.pre_index - PRE_SAMPLES + 1  # the samples before the pre-impact mean
        trials.append(
            MeasuredTrial(
                id=entry.id,
                posture=entry.posture,
                reference_speed=entry.reference_normal_speed,
                tangential_speed=float(np.linalg.norm(tangential)) if tangential is not None else 0.0,
                q0=log.q[i0].copy(),
                dq0=log.dq[max(i0 - START_AVERAGE, 0) : i0 + START_AVERAGE + 1].mean(axis=0),
                servo_reference=servo_reference_from_commands(
                    log.q[0], log.dq[: START_AVERAGE + 1].mean(axis=0), log.dq_cmd[:i0], period
                ),
                dq_cmd=log.dq_cmd[i0:i1].copy(),
                control_period=period,
                jump=impact.dq_jump,
                impulse=impact.impulse,
                duration=impact.duration,
                torque=log.tau[first:last].mean(axis=0),
                q_pre=impact.q_pre,
                dq_pre=impact.dq_pre,
                torque_window=(first - i0, last - i0),
                dq_log=log.dq[i0:i1].copy(),
                tau_log=log.tau[i0:i1].copy(),
                jump_samples=(impact.pre_index - i0, impact.post_index - i0),
                scatter=(sample_variance(log.dq[:quiet], dq_step), sample_variance(log.tau[:quiet], tau_step)),
                force_period=float(np.median(np.diff(log.force_t))) if len(log.force_t) > 1 else None,
            )
        )
    if trials:
        noise = estimate_noise(trials)
        trials = [replace(t, noise=noise) for t in trials]
    return trials, skipped, ReplaySetting(dataset.header.surface, dataset.header.choice)


def encoder_steps(dataset) -> tuple[np.ndarray, np.ndarray]:
    """The quantisation steps of the logged dq and tau per joint (``noise.quantisation_step``):
    dq's as the manifest declares it (``encoder_step``), else, as tau's, the step common to every
    value the trials logged (0: not quantised)."""
    logs = [trial.log for trial in dataset.trials]
    if not logs:
        return np.zeros(0), np.zeros(0)
    declared = dataset.header.encoder_step
    dq_step = np.array(declared) if declared is not None else quantisation_step(np.vstack([log.dq for log in logs]))
    return dq_step, quantisation_step(np.vstack([log.tau for log in logs]))


def replay_log(scene, trial: MeasuredTrial):
    """The simulated log of ``trial`` replayed in ``scene``: from its start state, the servo
    reference rebuilt from its commands, driven by its logged commands."""
    return run_trial(
        scene,
        CommandReplay(trial.dq_cmd, scene.model.nv),
        trial.q0,
        trial.dq0,
        len(trial.dq_cmd) * trial.control_period,
        control_period=trial.control_period,
        servo_reference=trial.servo_reference,
    )


def simulated_log(setting: ReplaySetting, plant: PlantParameters, trial: MeasuredTrial, scene_of):
    """The replay of ``trial`` in the physical part of ``plant`` on ``setting`` (``scene_of()``
    builds its scene when needed), from the per-process cache when it was simulated before; None
    when the simulation is unstable."""
    physical = plant.physical()
    surface, choice = setting.surface, setting.choice
    key = (surface.point.tobytes(), surface.normal.tobytes(), surface.friction, physical, trial.id,
           choice.robot.name, repr(choice.tool.as_dict()),
           trial.q0.tobytes(), trial.dq0.tobytes(), trial.dq_cmd.tobytes(),
           plant.sensor_delay, velocity_scales(plant, len(trial.dq0)).tobytes())
    if key in _simulated:
        _simulated.move_to_end(key)
        return _simulated[key]
    try:
        log = replay_log(scene_of(), true_start(trial, plant))
    except SimulationUnstableError:
        log = None
    _simulated[key] = log
    if len(_simulated) > REPLAY_CACHE_SIZE:
        _simulated.popitem(last=False)
    return log


def true_start(trial: MeasuredTrial, plant: PlantParameters) -> MeasuredTrial:
    """``trial`` starting from the true velocity that the sensor of ``plant`` logged as its
    start velocity: read ``sensor_delay`` samples later (the log is late) and divided by
    the velocity scales (``sim.sensor.velocity_scales``; the replay's physics must start from
    the robot's state, not from the faulty reading)."""
    scales = velocity_scales(plant, len(trial.dq0))
    if plant.sensor_delay == 0.0 and np.all(scales == 1.0):
        return trial
    ahead = delayed(trial.dq_log, -plant.sensor_delay)[: START_AVERAGE + 1].mean(axis=0)
    dq0 = trial.dq0 + ahead - trial.dq_log[: START_AVERAGE + 1].mean(axis=0)
    return replace(trial, dq0=dq0 / scales)


def replay(log, trial: MeasuredTrial) -> ReplayFeatures:
    """Measure the replayed ``log`` of one trial (after its sensor) like the real one: its jump
    at the trial's ``jump_samples``, its impulse and duration from its contact force.

    A replay that MuJoCo flags as unstable (bad accelerations, e.g. a servo gain beyond what the
    1 kHz loop can hold) is marked failed: its jump and impulse are zero, so the fit's residuals
    push away from it; so are the impulse and the detected jump of a replay without an impact.
    """
    joints = len(trial.dq0)
    if log is None:
        trace = np.zeros_like(trial.reference_trace)
        return ReplayFeatures(np.zeros(joints), np.zeros(3), 0.0, np.zeros(joints), np.zeros(joints), trace)
    first, last = trial.torque_window
    torque = log.tau[first:last].mean(axis=0)
    jump = jump_at(log.dq, *trial.jump_samples)
    trace = impact_trace(log.dq, log.tau, trial.jump_samples[0])
    try:
        impact = measure_impact(log)
    except ImpactNotFoundError:
        return ReplayFeatures(jump, np.zeros(3), 0.0, torque, np.zeros(joints), trace)
    return ReplayFeatures(jump, impact.impulse, impact.duration, torque, impact.dq_jump, trace)


def locate_jump_samples(trials: list[MeasuredTrial], setting: ReplaySetting, plant: PlantParameters) -> list[MeasuredTrial]:
    """The trials with the post-impact sample of their ``jump_samples`` taken from their replay
    in ``plant`` (the nominal one) instead of the measured velocities.

    ``controller.measured.impact`` reads the jump at the sample of largest change, which encoder
    noise biases towards larger jumps when the velocities are noisy (a positive noise sample is
    likelier to be the largest). The replay is noise-free, so its sample is chosen without the
    measured noise, the measured jump read there is unbiased, and the fit reads every replay at
    the same fixed samples: no cause can move the sample the data are read at, and the read
    jump is smooth in the parameters (``docs/diagnosis.md``). A trial whose replay finds no
    impact keeps its measured samples."""
    scene = setting.scene(plant)
    located = []
    for trial in trials:
        try:
            post = measure_impact(replay_log(scene, trial)).post_index
        except (SimulationUnstableError, ImpactNotFoundError):
            located.append(trial)
            continue
        pre = trial.jump_samples[0]
        located.append(replace(trial, jump_samples=(pre, max(post, pre + 1))))
    return located


def replay_all(setting: ReplaySetting, plant: PlantParameters, trials: list[MeasuredTrial]) -> list[ReplayFeatures]:
    """The features of every trial replayed in ``plant``: simulated in its physical part (or
    taken from the cache), then seen through its sensor (``sim.sensor.apply_sensor``)."""
    scene = []

    def scene_of():
        if not scene:
            scene.append(setting.scene(plant.physical()))
        return scene[0]

    features = []
    for trial in trials:
        log = simulated_log(setting, plant, trial, scene_of)
        if log is not None:
            log = apply_sensor(log, plant, trial.control_period)
        features.append(replay(log, trial))
    return features
