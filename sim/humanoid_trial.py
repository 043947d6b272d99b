"""One simulated hand impact of the standing G1, and a campaign of them (docs/floating-base.md).

Trial: the robot starts at rest in a stance (``controller.model.humanoid_stance``), the wall
the source's ``gap`` beyond its contact point. It stands still for :data:`SETTLE` s, then the right arm
(shoulder, elbow, wrist: its description's ``contact.joints``) is driven so that the hand moves along +x at ``speed``:
dq_arm = J_arm^+ v* (J_arm the arm joints' block of the contact Jacobian), reached by a 20 ms velocity
ramp; every other joint is commanded at rest. At the first wall contact (plus a 5 ms detection
latency) the arm stops: the servo's reference is re-anchored at the measured joint positions, at
rest (``ComputedTorqueServo.hold``), and the command is zero from then on; the trial goes on for :data:`AFTER` s
to see whether the robot stands. Why re-anchor rather than only command zero velocity: the wall has
already stopped the hand, but the reference still moves at the approach speed, so a zero command
asks the servo for the reference's whole deceleration -dq_ref/dt in one control step; the waist and
shoulder torques saturate and the reaction jolts the feet (what that stop did: docs/results.md,
"G1: servo and stop"). Re-anchored, the servo only damps the joints' post-impact velocities.
That is the default command source (``sim.trial_sources.SCRIPTED``); ``source`` chooses another
one, e.g. the whole-body QP (``sim.trial_sources.QpCommand``): a source (``TrialSource``) gives its
start gap, the time it may take to reach the wall (``approach_time``), per trial a driver, the
command source of the one trial loop (``sim.trial_loop``: ``step(q, v)`` returns the joints'
velocity command, ``stop()`` tells it that LATENCY has passed since the first contact), and whether
the servo re-anchors its reference at the stop (``holds_at_stop``). The trial runs in the one
trial runner of every robot (``sim.runner.run_impact``).

Servo (the kinematic control, the arm's: ``sim.servo.ComputedTorqueServo``, standing on the feet
through ``sim.servo.StandingSupport``): a joint-space computed-torque PD with acceleration
feed-forward on the joints, tau = M_f (ddq_ref + w^2 e + 2 w de) + h_j - tau_feet, with M_f the
joints' inertia with the base floating and tau_feet the joint torques of the least-norm foot
wrenches that carry the robot's weight in the measured configuration (every control step: the
weight's share between the feet and their moments follow the posture, which the whole-body QP
leans; wrenches of the start stance would leave the ankles a steady tracking error). The torque
each joint gets is clipped at its URDF effort limit (5-139 N m).

Plant: MuJoCo's G1 with the actuators' reflected rotor inertias by default (``armature``:
``sim.scene.plant_armature``; 0 for the link-only plant). The servo's M_f includes them
(MuJoCo's M does); the predictors do not (they keep the URDF model).

Measurement (a ``controller.measured.impact.ImpactMeasurement`` of the wall force): the state before the impact is the last control step before the wall's first
contact force, the state after it the first control step after that first contiguous contact
ends (at most :data:`WINDOW` s later). The measured impulse is the integral of the wall force over
that contact, and its peak (``peak_force``: the largest normal wall force of a physics step);
their ratio is the contact's equivalent duration (``equivalent_duration``, the T of the closed
form's foot criteria). The jump is compared over the joints with each predictor of
``controller.model.jump`` fed its own impulse, and with the feet-held momentum law fed
the measured impulse (``momentum``); the error is eq. (26), the mean of |predicted - measured|.

Failures: the criteria of a robot with held contacts (``sim.observed_criteria``: joint velocity
after the settling, foot slip and lift in the impact window, capture, fell), each with its onset
time, the same definitions as the closed form's criteria (``controller.model.max_speed``) measured
in the trial; the result's ``criteria`` (``sim.trial_result.TrialResult``) lists them, the failures and their onsets derive from it.

Log: ``TrialResult.log`` holds the trial as a robot logs it (``controller.measured.trial_log``): per control
step the joints' state, the servo's torque held over the step, the command, the base state, and the wall
force per physics step (``sim.generation`` writes it as a dataset).

The feet's displacements are kept beside them, with the CoM and the wall's peak force, in the
result's ``held`` (``sim.trial_result.HeldContactResult``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.measured.impact import ImpactMeasurement
from impactqp.controller.model.jump import jump_from_impulse, predict
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.robot_description import Stance

from .humanoid_feet import SPEED
from .observed_criteria import TrialObservation, observe
from .runner import run_impact, servoed_plant
from .scene import build_humanoid_scene
from .trial_loop import Ending
from .trial_result import HeldContactResult, TrialResult
from .trial_sources import SCRIPTED, TrialStart

CONTROL_PERIOD = 1e-3
SETTLE = 0.1  # s standing still before the approach
LATENCY = 0.005  # s from the first contact to the stop command
AFTER = 0.4  # s simulated after the impact
SINK = 0.001  # m the soles start into the floor
WINDOW = 0.03  # s: longest first contact read as the impact
SERVO_GAIN = 40.0  # rad/s
NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall's normal, towards the robot


def run_impact_trial(robot: RobotModel, stance: Stance, speed: float, *, gain: float = SERVO_GAIN,
                     armature=None, q0: np.ndarray | None = None, gap: float | None = None, source=SCRIPTED) -> TrialResult:
    """Simulate one trial (module docstring; ``sim.runner.run_impact``) and compare the jump with
    the predictors; ``gap`` (m) is the start distance of the contact point from the wall (None:
    the source's), ``armature`` the plant's rotor inertia (``sim.scene.plant_armature``: None for
    the G1's actuators), ``source`` the command source (``sim.trial_sources``: ``SCRIPTED``, or
    ``QpCommand``: the whole-body QP)."""
    q0 = stance_posture(robot, stance) if q0 is None else q0
    gap = source.gap if gap is None else gap
    contact0 = robot.frame_placements(q0)[robot.model.frames[robot.contact_frame_id].name].translation
    scene = build_humanoid_scene(robot, wall_x=float(contact0[0]) + gap, armature=armature)
    plant = servoed_plant(scene, robot, CONTROL_PERIOD, gain)
    contact = robot.terms(q0).contact_point
    wall = Surface(np.array([scene.wall_x, contact[1], contact[2]]), NORMAL.copy())
    ending = Ending(
        int(round((SETTLE + source.approach_time(gap, speed)) / CONTROL_PERIOD)), after=int(round(AFTER / CONTROL_PERIOD)),
        stop_after=int(round(LATENCY / CONTROL_PERIOD)), hold=source.holds_at_stop,
    )
    run = run_impact(plant, source, TrialStart(robot, q0, np.zeros(robot.nv), wall, speed, settle=SETTLE, sink=SINK,
                                               control_period=CONTROL_PERIOD), ending)
    record = run.record
    first = record.first_contact
    if first is None:
        raise RuntimeError(f"the hand never reached the wall (stance {stance.name}, {speed} m/s, {source.name} command)")
    walls = record.force.reshape(len(record.t), plant.substeps, 3)
    forces, peaks = (walls * scene.timestep).sum(axis=1), np.maximum((walls @ NORMAL).max(axis=1), 0.0)
    return _evaluate(robot, (stance.name, speed), _Contact(forces, peaks, first), run, scene.wall_x, source)


@dataclass(frozen=True)
class _Contact:
    """The wall per control step: its impulse on the robot (steps, 3), the sum of its physics
    steps', and its largest normal force of a physics step (steps,) (N, 0 without one); the
    control step of the first wall contact."""

    forces: np.ndarray
    peaks: np.ndarray
    first: int

    @property
    def last(self) -> int:
        """The last control step of the first contiguous contact (at most WINDOW s long)."""
        last, window = self.first, int(round(WINDOW / CONTROL_PERIOD))
        while last + 1 < min(len(self.forces), self.first + window) and np.any(self.forces[last + 1] != 0.0):
            last += 1
        return last


def _evaluate(robot, trial: tuple[str, float], contact: _Contact, run, wall_x: float, source) -> TrialResult:
    """The measured impact, the predicted jumps and the observed criteria of a simulated trial
    ``run`` (``sim.runner.TrialRun``; module docstring) of ``trial`` = (stance, commanded speed)."""
    log, held = run.log, run.record.held
    first, last = contact.first, contact.last
    start = int(round(SETTLE / CONTROL_PERIOD))
    watched = np.arange(len(log)) >= start
    terms = robot.terms(np.concatenate([log.base[first, :robot.base_nq], log.q[first]]))
    o = TrialObservation(
        robot, log, watched, first, last, contact.forces[first:last + 1].sum(axis=0),
        (last + 1 - first) * CONTROL_PERIOD, terms.J, CONTROL_PERIOD, held,
    )
    q_pre, v_pre = o.state(first)
    q_post, v_post = o.state(o.post)
    impulse = o.impulse
    v_minus = terms.J @ v_pre
    measured = v_post - v_pre
    predicted, com, impulses = {}, {}, {}
    for method in METHODS:
        jump = predict(terms, method, NORMAL, v_minus)
        predicted[method], com[method], impulses[method] = jump.dq_jump, jump.com_jump, jump.impulse
    predicted["momentum"] = jump_from_impulse(terms, impulse)
    com["momentum"] = terms.Jcom @ predicted["momentum"]
    impulses["momentum"] = impulse
    post_com_velocity = robot.terms(q_post).Jcom @ v_post
    joints = slice(robot.base_nv, None)
    t_contact = first * CONTROL_PERIOD
    impact = ImpactMeasurement(
        "force", t_contact, t_contact, first, first, o.post, (first, last), q_pre[robot.base_nq:], v_pre[joints],
        v_post[joints], measured[joints], impulse, o.duration,
    )
    soles = held.soles[o.impact_window()]
    moved = held.feet[start:] - held.feet[start]
    feet = HeldContactResult(
        peak_force=float(contact.peaks[first:last + 1].max()), floor_impulse=held.floor[first:last + 1].sum(axis=0),
        measured_com_jump=post_com_velocity - terms.Jcom @ v_pre, predicted_com_jump=com, predicted_impulse=impulses,
        post_com_velocity=post_com_velocity, foot_slip=float(np.linalg.norm(moved[..., :2], axis=-1).max()),
        foot_lift=float(np.abs(moved[..., 2]).max()), slide_speed=float(soles[:, o.loaded_before(), SPEED].max()),
        wall_x=wall_x, wall_normal=NORMAL.copy(), q_log=np.column_stack([log.base[:, :robot.base_nq], log.q]),
    )
    stance, speed = trial
    return TrialResult(
        trial_id=f"{stance}_vn{round(speed * 1000):d}_{source.name}", posture=stance, normal_speed=speed,
        tangential_velocity=np.zeros(3), jump_model=None, log=log, impact=impact, measured_jump=measured, contact_speed=float(-NORMAL @ v_minus),
        predicted=predicted, criteria=observe(o), source=source.name, record=run.driver.record, held=feet,
    )
