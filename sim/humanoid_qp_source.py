"""The whole-body QP as the command source of the simulated G1 trial (docs/floating-base.md,
"Trials driven by the whole-body QP").

``run_impact_trial(..., source=QpCommand())`` drives the joints with the robot's default
controller (``ControllerConfig.approach``) instead of the scripted arm command:

- the controller is built for the stance (``ControllerConfig.approach(the wall, the trial's
  hand speed, robot=the robot's description)``: the wall plane at ``wall_x`` with normal -x; its support polygon is the start
  stance's) and reset at the state measured when the settling ends (its CoM, torso and posture
  targets are that state's);
- during the settling the joints are held (zero command, as the scripted source); from then on,
  every 1 ms control step, the controller is given the state (Pinocchio convention) and the
  joints' part of its ``v_cmd`` goes to the trial's servo, which integrates it (kinematic control);
- at the stop (the trial's LATENCY after the first wall contact) the hand's approach speed target
  becomes 0 (``ContactApproachTask.reference_velocity``): the QP brakes within its acceleration
  and jerk limits. Why the task target and not a second reset: a reset would re-capture the CoM,
  torso and posture targets at the post-impact state (keeping whatever the impact displaced) and
  zero the controller's acceleration memory, a step of acceleration that skips the jerk limit.

``feedback`` says which state the controller is given: ``"measured"`` (the plant's state,
``to_pinocchio``) or ``"commanded"`` (its own previous (q_cmd, v_cmd), the measured state only at
the reset; the arm's convention of ``scenarios.trial``, where measured feedback closes a positive
loop through the servo's acceleration feed-forward).

Each control step's status, the impact rows' activity and the predicted post-impact velocity at
the command (``Command.predicted_post_impact_velocity``) are kept in a ``QpRecord``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp.command import Command, Status
from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.tasks import ContactApproachTask

from .humanoid_trial import CONTROL_PERIOD, LAG, NORMAL, RAMP, SETTLE
from .trial_loop import FEEDBACK, ControllerSource, VelocityCommand
IMPACT_ROWS = "post_impact_velocity"  # name prefix of the predicted post-impact joint-velocity rows
CAPTURE_ROWS = "capture_region"  # name prefix of the capture-region rows
QP_GAP = 0.05  # m from the contact point to the wall at the start (docs/floating-base.md: room to accelerate)
HAND_ACCELERATION = 2.0  # m/s^2: a lower bound of the hand's acceleration under the QP's joint limits


@dataclass(frozen=True)
class QpCommand:
    """The whole-body QP as a trial's command source (module docstring): jump predictor of the
    impact rows (crb, gm or classical), QP solver and which state the controller is given."""

    method: str = "crb"
    solver: str = "daqp"
    feedback: str = "commanded"
    gap: float = QP_GAP
    name = "qp"
    tracks_speed = True  # the hand's task asks the speed itself; the QP's rows and limits may cap it
    holds_at_stop = False  # the QP brakes the joints itself (its acceleration and jerk limits)

    def __post_init__(self):
        if self.feedback not in FEEDBACK:
            raise BadInputError(f"unknown feedback {self.feedback!r}; choose from {', '.join(FEEDBACK)}")

    def approach_time(self, gap: float, speed: float) -> float:
        """s allowed from the end of the settling to the first wall contact: three times the gap
        at the asked speed, plus the time to reach it at HAND_ACCELERATION, plus the scripted
        source's ramp and lag margin."""
        return 3 * gap / speed + speed / HAND_ACCELERATION + RAMP + LAG

    def start(self, robot: RobotModel, q0: np.ndarray, wall_x: float, speed: float) -> QpDriver:
        """The driver of one trial: the controller of the stance q0 towards the wall plane x = wall_x."""
        contact = robot.terms(q0).contact_point
        wall = Surface(np.array([wall_x, contact[1], contact[2]]), NORMAL.copy())
        config = ControllerConfig.approach(
            wall, speed, robot=RobotChoice(robot.description).robot_setting, jump_model=self.method, solver=self.solver
        )
        return QpDriver(build_controller(config, robot, q0), self.feedback)


@dataclass
class QpRecord:
    """What the QP did at each control step after the settling (``steps`` from its first cycle)."""

    first_step: int = 0  # the trial's control step of the QP's first cycle
    statuses: list = field(default_factory=list)  # Status of each cycle
    impact_rows_active: list = field(default_factory=list)  # a post-impact velocity row tight at the solution
    capture_rows_active: list = field(default_factory=list)  # a capture-region row tight at the solution
    impact_constraints_on: list = field(default_factory=list)  # the activation rule switched the impact rows on
    predicted_post_impact: list = field(default_factory=list)  # (nv) v_cmd + predicted jump of each cycle
    messages: list = field(default_factory=list)  # the message of each cycle whose status is not OK

    def add(self, command: Command) -> None:
        self.statuses.append(Status(command.status))
        self.impact_rows_active.append(any(n.startswith(IMPACT_ROWS) for n in command.active_constraints))
        self.capture_rows_active.append(any(n.startswith(CAPTURE_ROWS) for n in command.active_constraints))
        self.impact_constraints_on.append(bool(command.impact_constraints_active))
        self.predicted_post_impact.append(command.predicted_post_impact_velocity.copy())
        if command.status != Status.OK:
            self.messages.append(command.message)

    @property
    def not_ok(self) -> int:
        """Cycles whose status is not OK (a clipped velocity or a fallback)."""
        return sum(s != Status.OK for s in self.statuses)

    def cycle(self, step: int) -> int:
        """The QP cycle of the trial's control step ``step``."""
        return step - self.first_step


class QpDriver:
    """One trial of ``QpCommand``, a stopping command source (``sim.trial_loop``): ``step(q, v)`` ->
    the joints' dq_cmd at the source's control step."""

    def __init__(self, controller, feedback: str):
        self.controller, self.source = controller, ControllerSource(controller, feedback)
        self.approach = next(t for t in controller.tasks if isinstance(t, ContactApproachTask))
        self.record = QpRecord()
        self._step = 0

    def stop(self) -> None:
        """The hand's approach speed target becomes 0 (module docstring)."""
        self.approach.reference_velocity = np.zeros(3)

    def step(self, q_pin: np.ndarray, v_pin: np.ndarray) -> VelocityCommand:
        step, self._step = self._step, self._step + 1
        if step * CONTROL_PERIOD < SETTLE:
            return VelocityCommand(np.zeros(self.controller.robot.n_joints))
        if self.source.last is None:
            self.controller.reset(q_pin, v_pin)
            self.record.first_step = step
        command = self.source.step(q_pin, v_pin)
        self.record.add(self.source.last)
        return VelocityCommand(command.dq_cmd.copy())
