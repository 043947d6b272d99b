"""The command sources of a trial, every robot's (``sim.runner``: the one trial runner).

A trial's command source (:class:`TrialSource`) is given, at the start of one trial, the robot,
its start state, the wall and the commanded speed (:class:`TrialStart`), and returns the driver
of that trial: a command source of the trial loop (``sim.trial_loop.CommandSource``:
``step(q, dq)`` -> the joints' ``dq_cmd``, once per control period; ``stop()`` when the loop's
``Ending.stop_after`` says the approach ends). A robot standing on held contacts first settles
on them for ``TrialStart.settle`` s, during which every source commands the joints at rest.

- :class:`CartesianApproach` (the arm's plain approach, :class:`CartesianApproachCommand`):
  dq_cmd = J6+ [-v_n n + v_t; 0], open loop in task space, never stops;
- :class:`ScriptedCommand` (the standing robot's scripted arm): the joints that move the
  contact (the description's ``contact.joints``) follow dq_arm = J_arm^+ v* after a :data:`RAMP`
  s velocity ramp, every other joint at rest; at the stop the servo re-anchors its reference at
  the measured joints, at rest (``holds_at_stop``), and the command is zero;
- :class:`QpCommand` (every robot: the default controller ``ControllerConfig.approach`` of the
  robot's description, with the jump predictor of its impact rows; a standing robot's trial starts
  from its run-up, ``controller.model.run_up``): the controller is reset at the
  state measured when the settling ends (at once for a fixed base) and is given, every period, its
  own previous command (``feedback="commanded"``, a fixed-base arm's default: a kinematic-controlled robot's
  convention, ``scenarios.trial`` says why), the measured state, or a blend of the two
  (``"blended"``: ``sim.trial_loop.ControllerSource``; a standing robot's default: fed its own
  command its QP believes its centre of mass millimetres from the plant's, where the foot rows
  bind up to 12 % lower, docs/whole-body-qp.md); at the stop the hand's approach speed
  target becomes 0 (``ContactApproachTask.reference_velocity``): the QP brakes within its
  acceleration and jerk limits, and a standing robot's controller is given from then on the
  state of ``balance_feedback`` (None: the approach's own state, or the blended one when the
  approach is fed its own command, which would not see the body the impact set moving: the
  close stance fell 0.4 s after its impact) and, when
  that state sees its body, turns to its balance (``controller.config.post_impact_balance``).
  Why the task target and not a second reset: a reset would re-capture the CoM, torso
  and posture targets at the post-impact state and zero the controller's acceleration memory, a
  step of acceleration that skips the jerk limit. Each cycle's status, the impact rows' activity
  and the predicted post-impact velocity are kept in a :class:`QpRecord`;
- :class:`CommandReplay`: a logged sequence of commands, one row per period.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.config.controller_config import FLOATING_BASE_APPROACH
from impactqp.controller.config.post_impact_balance import balance_after_impact
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.max_speed import Setting, closed_form_max_speed, contact_joints
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.run_up import run_up_distance, run_up_posture
from impactqp.controller.model.validation import BadInputError, approach_speed
from impactqp.controller.model.validation import tangential_velocity as tangential_velocity_along
from impactqp.controller.qp.command import Command, Status
from impactqp.tasks import ContactApproachTask

from .trial_loop import FEEDBACK, CommandSource, ControllerSource, VelocityCommand

RAMP = 0.02  # s of the scripted command's velocity ramp
LAG = 0.1  # s the hand may arrive after the commanded arrival (torque-limited joints lag the command)
HAND_ACCELERATION = 2.0  # m/s^2: a lower bound of the hand's acceleration under the QP's joint limits
SCRIPTED_GAP = 0.02  # m from the contact point to the wall at the start of a standing robot's scripted trial
IMPACT_ROWS = "post_impact_velocity"  # name prefix of the predicted post-impact joint-velocity rows
CAPTURE_ROWS = "capture_region"  # name prefix of the capture-region rows
FOOT_ROWS = "foot_wrench"  # name prefix of the feet's rows at the impact
BINDING_WINDOW = 10  # QP cycles before a step whose tight impact rows bind the approach (``QpRecord.binding``)


@dataclass(frozen=True)
class TrialStart:
    """What a command source is given at the start of one trial: the robot, its start state (q0,
    dq0) (Pinocchio convention), the wall (normal towards the robot), the commanded normal speed
    v_n (m/s) and tangential velocity v_t, the settling time (s) before the approach, how far
    (m) the plant starts below q0 (a robot standing on held contacts: its soft floor contact
    carries the weight from the first step), the control period (s) and the posture the hand
    should meet the wall in (a standing robot's stance, whose closed form is quoted, when the trial
    starts from its run-up; None: q0)."""

    robot: RobotModel
    q0: np.ndarray
    dq0: np.ndarray
    surface: Surface
    speed: float
    tangential_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    settle: float = 0.0
    sink: float = 0.0
    control_period: float = 1e-3
    contact_posture: np.ndarray | None = None

    def plant_start(self) -> np.ndarray:
        """The plant's start configuration: q0, ``sink`` m lower (unchanged without a sink)."""
        if not self.sink:
            return self.q0
        q = self.q0.copy()
        q[2] -= self.sink
        return q


class TrialSource(Protocol):
    """A trial's command source (module docstring): its name, whether the servo re-anchors its
    reference at the stop, and the driver of one trial."""

    name: str
    holds_at_stop: bool

    def start(self, start: TrialStart) -> CommandSource: ...


class CartesianApproachCommand:
    """Move the contact point at a constant world velocity with the orientation held.

    dq_cmd = J6+ [v_ref; 0], v_ref = -v_n n + v_t, with J6 the 6 x n_joints (linear; angular)
    Jacobian of the contact frame and J6+ its Moore-Penrose pseudo-inverse (minimum joint-velocity
    norm). A purely kinematic, open-loop-in-task-space approach: no drift correction, which is
    harmless over the few centimetres of an impact trial. It never stops: after the impact it keeps
    commanding motion into the wall (the servo then presses with a slowly growing force).
    """

    def __init__(self, robot: RobotModel, surface: Surface, normal_speed: float,
                 tangential_velocity: np.ndarray | None = None):
        approach_speed(normal_speed, "normal_speed")
        v_t = np.zeros(3) if tangential_velocity is None else tangential_velocity_along(tangential_velocity, surface.normal)
        self.robot = robot
        self.twist = np.concatenate([-normal_speed * surface.normal + v_t, np.zeros(3)])

    def step(self, q: np.ndarray, dq: np.ndarray) -> VelocityCommand:
        J6 = self.robot.contact_jacobian6(q)
        return VelocityCommand(np.linalg.lstsq(J6, self.twist, rcond=None)[0])


@dataclass(frozen=True)
class CartesianApproach:
    """:class:`CartesianApproachCommand` as a trial's command source (an arm's plain approach)."""

    name = "cartesian"
    holds_at_stop = False

    def start(self, start: TrialStart) -> CartesianApproachCommand:
        return CartesianApproachCommand(start.robot, start.surface, start.speed, start.tangential_velocity)


class CommandReplay:
    """Replay a logged sequence of joint-velocity commands of ``joints`` joints, one row per
    control step."""

    def __init__(self, dq_cmd: np.ndarray, joints: int):
        dq_cmd = np.asarray(dq_cmd, dtype=float)
        if dq_cmd.ndim != 2 or dq_cmd.shape[1] != joints or len(dq_cmd) == 0:
            raise BadInputError(f"a command replay needs an (N, {joints}) array, got shape {dq_cmd.shape}")
        if not np.all(np.isfinite(dq_cmd)):
            raise BadInputError("the replayed commands contain a non-finite value")
        self.dq_cmd = dq_cmd
        self.index = 0

    def __len__(self) -> int:
        return len(self.dq_cmd)

    def step(self, q: np.ndarray, dq: np.ndarray) -> VelocityCommand:
        if self.index >= len(self.dq_cmd):
            raise IndexError(f"the command replay holds only {len(self.dq_cmd)} control steps")
        command = VelocityCommand(self.dq_cmd[self.index])
        self.index += 1
        return command


@dataclass(frozen=True)
class ScriptedCommand:
    """The scripted arm of a standing robot (module docstring)."""

    name = "scripted"
    gap = SCRIPTED_GAP  # m from the contact point to the wall at the start
    tracks_speed = False  # the servo lags the command: the contact speed is below the commanded one
    holds_at_stop = True  # the servo re-anchors its reference at the stop (``ComputedTorqueServo.hold``)

    def approach_time(self, gap: float, speed: float) -> float:
        """s allowed from the end of the settling to the first wall contact."""
        return 3 * gap / speed + RAMP + LAG

    def start_posture(self, robot: RobotModel, q: np.ndarray, normal: np.ndarray, speed: float) -> tuple[np.ndarray, float]:
        """The trial's start posture and gap (m) from a stance's posture q: q itself, :attr:`gap`."""
        return q, self.gap

    def start(self, start: TrialStart) -> _ScriptedDriver:
        return _ScriptedDriver(start)


class _ScriptedDriver:
    """One trial of :class:`ScriptedCommand`, a stopping command source (``sim.trial_loop``):
    ``step(q, v)`` -> the joints' dq_cmd at the source's control step, zero once stopped."""

    def __init__(self, start: TrialStart):
        robot = start.robot
        self.robot, self.speed, self.normal = robot, start.speed, start.surface.normal
        self.settle, self.period = start.settle, start.control_period
        self.arm = np.array([robot.joint_index(j) for j in contact_joints(robot.description)])
        self.record = None
        self.stopped = False
        self._step = 0

    def stop(self) -> None:
        self.stopped = True

    def step(self, q_pin: np.ndarray, v_pin: np.ndarray) -> VelocityCommand:
        t, self._step = self._step * self.period, self._step + 1
        dq_cmd = np.zeros(self.robot.n_joints)
        if t >= self.settle and not self.stopped:
            terms = self.robot.terms(q_pin)
            scale = min(1.0, (t - self.settle) / RAMP)
            arm = self.robot.base_nv + self.arm  # the arm joints' columns of J
            dq_cmd[self.arm] = np.linalg.pinv(terms.J[:, arm]) @ (-scale * self.speed * self.normal)
        return VelocityCommand(dq_cmd)


SCRIPTED = ScriptedCommand()
CARTESIAN = CartesianApproach()


@dataclass(frozen=True)
class QpCommand:
    """The robot's default controller as a trial's command source (module docstring): the jump
    predictor of its impact rows (``method``: a jump model, None without the rows), the QP solver,
    which state it is given during the approach (``feedback``; None: "blended" for a robot with
    held contacts, else "commanded") and, a standing robot, from the stop on
    (``balance_feedback``), the start gap of a standing robot's trial (m), and the approach
    options c_r, delta_t, the posture task's weight (None: the preset's) and the friction mu of
    the robust friction rows (None or 0: none; docs/frictional-impacts.md), which a standing
    robot's wall takes too (None: the paper's mu, ``sim.runner.standing_wall_friction``). A
    standing robot's trial starts from its run-up (``gap`` None, :meth:`start_posture`) or ``gap``
    m from the wall at the stance's posture. ``governor``: with the impact rows on and the contact
    posture known, the hand's speed target is capped at this share of the closed form's highest
    speed there (:meth:`governed_speed`; None: the asked speed)."""

    method: str | None = "crb"
    solver: str = "daqp"
    feedback: str | None = None
    balance_feedback: str | None = None
    gap: float | None = None
    restitution: float = 0.0
    impact_duration: float | None = None
    posture_weight: float | None = None
    friction: float | None = None
    governor: float | None = 1.0
    name = "qp"
    tracks_speed = True  # the hand's task asks the speed itself; the QP's rows and limits may cap it
    holds_at_stop = False  # the QP brakes the joints itself (its acceleration and jerk limits)

    def __post_init__(self):
        for feedback in (self.feedback, self.balance_feedback):
            if feedback is not None and feedback not in FEEDBACK:
                raise BadInputError(f"unknown feedback {feedback!r}; choose from {', '.join(FEEDBACK)}")

    def approach_time(self, gap: float, speed: float) -> float:
        """s allowed from the end of the settling to the first wall contact: three times the gap
        at the asked speed, plus the time to reach it at HAND_ACCELERATION, plus the scripted
        source's ramp and lag margin."""
        return 3 * gap / speed + speed / HAND_ACCELERATION + RAMP + LAG

    def governed_speed(self, robot: RobotModel, contact_posture: np.ndarray | None, normal: np.ndarray, speed: float) -> float:
        """The hand's speed target (m/s) for the asked ``speed``: a reference governor that keeps
        the approach from accelerating past what its impact rows will allow at the wall,

            v* = min(v, governor v_max(q_c)),

        v_max(q_c) the closed form's highest speed at the contact posture q_c
        (``max_speed.closed_form_max_speed``, the rows' own predictor, restitution and impact
        duration: along the approach its rows hold exactly up to it). The rows bound the command
        one jerk horizon ahead; asked above v_max the command runs up faster than the rows will
        allow and brakes when they tighten, and a plant that lags the command's braking meets the
        wall faster than the rows allow (docs/whole-body-qp.md, "The wall at the stance's hand, the
        governor and the blend"). The asked speed without the rows, the contact posture or a
        ``governor``."""
        if self.governor is None or self.method is None or contact_posture is None:
            return speed
        setting = Setting(self.method, self.restitution, impact_duration=self.impact_duration)
        bound = closed_form_max_speed(robot, robot.terms(contact_posture), normal, setting).speed
        return min(speed, self.governor * bound)

    def start_posture(self, robot: RobotModel, q: np.ndarray, normal: np.ndarray, speed: float) -> tuple[np.ndarray, float]:
        """The trial's start posture and gap (m) from a stance's posture q: the run-up
        (``controller.model.run_up``: the hand moved back along the normal n far enough for the
        hand's task to reach the governed ``speed``) and the wall at the stance's hand, so that the
        hand meets it in the stance's posture, the one whose closed form is quoted and governs (the
        wall 2 cm beyond it, the scripted arm's gap, met the arm 2 cm past it, where the closed form
        is up to 16 % lower: docs/whole-body-qp.md); with a ``gap``, q itself and that gap."""
        if self.gap is not None:
            return q, self.gap
        speed = self.governed_speed(robot, q, normal, speed)
        start = run_up_posture(robot, q, normal, run_up_distance(speed, FLOATING_BASE_APPROACH["velocity_gain"]))
        moved = (robot.terms(start).contact_point - robot.terms(q).contact_point) @ normal
        return start, float(moved)

    def config(self, start: TrialStart) -> ControllerConfig:
        """The controller's configuration: the description's approach towards the start's wall at
        the governed speed (:meth:`governed_speed`); with a ``contact_posture``, the hand's
        orientation target is the contact posture's (the run-up turned the hand: held at the
        run-up's orientation, the arm reached the wall in another posture than the stance's, where
        the foot rows bind lower; docs/whole-body-qp.md)."""
        options = {} if self.impact_duration is None else {"impact_duration": self.impact_duration}
        speed = self.governed_speed(start.robot, start.contact_posture, start.surface.normal, start.speed)
        config = ControllerConfig.approach(
            start.surface, speed, tangential_velocity=start.tangential_velocity,
            robot=RobotChoice(start.robot.description).robot_setting, jump_model=self.method, solver=self.solver,
            restitution=self.restitution, posture_weight=self.posture_weight,
            friction=0.0 if self.friction is None else self.friction, **options,
        )
        if start.contact_posture is None:
            return config
        rotation = start.robot.terms(start.contact_posture).contact_rotation
        tasks = [
            replace(t, params={**t.params, "target_rotation": rotation.tolist()}) if t.type == "contact_approach" else t
            for t in config.tasks
        ]
        return replace(config, tasks=tasks)

    def start(self, start: TrialStart) -> QpDriver:
        """The driver of one trial: the controller of the start posture towards the start's wall."""
        controller = build_controller(self.config(start), start.robot, start.q0)
        approach = self.feedback or ("blended" if start.robot.description.held_contacts else "commanded")
        balance = self.balance_feedback or ("blended" if approach == "commanded" else approach)
        return QpDriver(controller, (approach, balance), start.settle, start.control_period)


@dataclass
class QpRecord:
    """What the QP did at each control step after the settling (``steps`` from its first cycle)."""

    first_step: int = 0  # the trial's control step of the QP's first cycle
    speed_target: float = 0.0  # m/s: the hand's approach speed target (the governed asked speed)
    statuses: list = field(default_factory=list)  # Status of each cycle
    impact_rows_active: list = field(default_factory=list)  # a post-impact velocity row tight at the solution
    capture_rows_active: list = field(default_factory=list)  # a capture-region row tight at the solution
    tight_impact_rows: list = field(default_factory=list)  # names of the impact rows (joints, capture, feet) tight at the solution
    impact_constraints_on: list = field(default_factory=list)  # the activation rule switched the impact rows on
    predicted_post_impact: list = field(default_factory=list)  # (nv) v_cmd + predicted jump of each cycle
    messages: list = field(default_factory=list)  # the message of each cycle whose status is not OK

    def add(self, command: Command) -> None:
        self.statuses.append(Status(command.status))
        self.impact_rows_active.append(any(n.startswith(IMPACT_ROWS) for n in command.active_constraints))
        self.capture_rows_active.append(any(n.startswith(CAPTURE_ROWS) for n in command.active_constraints))
        self.tight_impact_rows.append(
            tuple(n for n in command.active_constraints if n.startswith((IMPACT_ROWS, CAPTURE_ROWS, FOOT_ROWS)))
        )
        self.impact_constraints_on.append(bool(command.impact_constraints_active))
        self.predicted_post_impact.append(command.predicted_post_impact_velocity.copy())
        if command.status != Status.OK:
            self.messages.append(command.message)

    @property
    def not_ok(self) -> int:
        """Cycles whose status is not OK (a clipped velocity or a fallback)."""
        return sum(s != Status.OK for s in self.statuses)

    def binding(self, step: int) -> tuple[str, ...]:
        """The impact rows tight in any of the BINDING_WINDOW QP cycles up to the trial's control
        step ``step`` (e.g. the first wall contact): what held the approach speed, sorted."""
        end = self.cycle(step) + 1
        return tuple(sorted({n for names in self.tight_impact_rows[max(end - BINDING_WINDOW, 0):max(end, 0)] for n in names}))

    def cycle(self, step: int) -> int:
        """The QP cycle of the trial's control step ``step``."""
        return step - self.first_step


class QpDriver:
    """One trial of :class:`QpCommand`, a stopping command source (``sim.trial_loop``): zero
    commands during the settling (``settle`` s), then the controller, reset at its first cycle at
    the measured state and given the state of ``feedback`` (the approach's, the balance's: from
    the stop on, a standing robot); ``step(q, v)`` -> the joints' dq_cmd at the source's control
    step."""

    def __init__(self, controller, feedback: tuple[str, str], settle: float = 0.0, control_period: float = 1e-3):
        (approach, self.balance_feedback), self.controller = feedback, controller
        self.source = ControllerSource(controller, approach)
        self.approach = next(t for t in controller.tasks if isinstance(t, ContactApproachTask))
        self.settle, self.period = settle, control_period
        self.record = QpRecord(speed_target=self.approach.speed)
        self._step = 0

    def stop(self) -> None:
        """The hand's approach speed target becomes 0 (module docstring); a standing robot's
        controller is given the balance's state from now on (``QpCommand.balance_feedback``) and,
        when that state sees its body (blended or measured), turns to its balance
        (``controller.config.post_impact_balance``: fed its own command it would balance a body it
        does not see)."""
        self.approach.reference_velocity = np.zeros(3)
        if not self.controller.robot.description.held_contacts:
            return
        self.source.feedback = self.balance_feedback
        if self.balance_feedback != "commanded":
            balance_after_impact(self.controller)

    def step(self, q_pin: np.ndarray, v_pin: np.ndarray) -> VelocityCommand:
        step, self._step = self._step, self._step + 1
        if step * self.period < self.settle:
            return VelocityCommand(np.zeros(self.controller.robot.n_joints))
        if self.source.last is None:
            self.controller.reset(q_pin, v_pin)
            self.record.first_step = step
        command = self.source.step(q_pin, v_pin)
        self.record.add(self.source.last)
        return VelocityCommand(command.dq_cmd.copy())
