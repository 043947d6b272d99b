"""The impact session: the controller of each phase, online impact detection and the switch.

Phases: ``approach`` (the configured controller with its impact-aware constraints) until the
impact is detected (``controller.runtime.impact_detector``: the robot's external-torque
estimate when it gives a real one, else the momentum observer on the measured torque,
``residual_source``; a floating base, whose held contacts' wrenches change with every motion,
by the jump of its measured velocity: ``velocity_jump``, the rule of the controller's impact
brake), then the
post-impact phase of ``config.post_impact`` (``retract``, ``hold`` or ``continue``: the
controller of ``controller.config.post_impact_config``, impact-aware constraints off).

Both controllers are built at the start, so the switch costs one ``reset``. The post-impact
controller starts from the approach controller's command memory (previous q_cmd, dq_cmd and
ddq), so its first command obeys the jerk limits around the last one. As in ``impactqp
simulate`` the approach controller is fed its own previous command (q_cmd, dq_cmd), the measured
state only at the start (``scenarios.trial``, "Controller state"). After the impact of a
``retract`` or ``hold`` it is fed the measured q with the commanded dq: the task is a position
relative to the surface and the bounce moved the tool off the commanded one
(``docs/robot-loop.md``, "Which state the controller sees").
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.config import ControllerConfig, build_controller, post_impact_config
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.qp import Command

from .impact_detector import ImpactDetector, MomentumObserver, VelocityJumpDetector
from .interface import RobotState

APPROACH = "approach"
MEASURED_POSITION_PHASES = ("hold", "retract")
ESTIMATE, OBSERVER, VELOCITY_JUMP = "estimate", "observer", "velocity_jump"


def residual_source(state: RobotState) -> str:
    """``estimate`` when the robot gives an external-torque estimate, else ``observer``.

    An estimate equal to the measured joint torque is not one: it still holds gravity, which a
    model-based estimate tau_ext = tau - (M ddq + h) removes, and gravity torques are never all
    zero on an arm standing in gravity. A simulator of the Franka protocol that reports
    ``tau_J`` as ``tau_ext_hat_filtered`` (franky-sim) gets the observer on ``tau_J``."""
    if state.tau_ext is None or np.array_equal(state.tau_ext, state.tau):
        return OBSERVER
    return ESTIMATE


class ImpactSession:
    """``start(state)`` once, then ``step(state) -> Command`` every period (``Command.phase``).
    ``q_start``: the configuration a floating base stands in (its support polygon; None: its
    default stance)."""

    def __init__(self, config: ControllerConfig, robot: RobotModel | None = None, q_start=None):
        robot = config.choice.model() if robot is None else robot
        self.robot = robot
        self.config = config
        self.approach = build_controller(config, robot, q_start)
        self.post_impact = build_controller(post_impact_config(config), robot, q_start)
        self.floating = robot.base_nv > 0
        if self.floating:
            self.observer, self.detector = None, VelocityJumpDetector(robot, self.approach.impact)
        else:
            self.observer = MomentumObserver(robot, config.dt)
            self.detector = ImpactDetector(robot.nv, settle_samples=self.observer.settle_samples)
        self.controller = self.approach
        self.phase = APPROACH
        self.last: Command | None = None
        self.last_approach: Command | None = None  # the approach phase's last command
        self.pre_impact_state: RobotState | None = None
        self._previous_state: RobotState | None = None
        self._start_t: float | None = None
        self.residual_source = OBSERVER

    def start(self, state: RobotState) -> None:
        """Reset at the first state; two discarded steps of each controller first, so that the
        solvers' set-up and the first call of each compiled kernel (the second step's: a solve in
        the set-up workspace) do not fall into the first control cycles."""
        q, dq = self.generalized(state)
        for controller in (self.post_impact, self.approach):
            controller.reset(q, dq)
            controller.step(q, dq)
            controller.step(q, dq)
            controller.reset(q, dq)
            controller.fallback_count = 0
        self._previous_state = state
        self._start_t = state.t
        if self.floating:
            self.residual_source = VELOCITY_JUMP
            return
        self.observer.reset(q, dq)
        self.residual_source = residual_source(state)

    def generalized(self, state: RobotState) -> tuple[np.ndarray, np.ndarray]:
        """The model's (q, dq) of a state: the joints' for a fixed base; a floating base's state
        (``state.base``) first, then the joints'."""
        if state.base is None:
            return state.q, state.dq
        nq = self.robot.base_nq
        return np.concatenate([state.base[:nq], state.q]), np.concatenate([state.base[nq:], state.dq])

    def residual(self, state: RobotState) -> np.ndarray:
        """The joint-torque residual of the detector: the robot's estimate or the observer's
        (``residual_source``). The observer starts at the start state (r = 0 there): its ``tau``
        acted before the start, over no period that p - p_0 saw, so it is not integrated."""
        if self.residual_source == ESTIMATE:
            return state.tau_ext
        if state.t == self._start_t:
            return self.observer.residual
        return self.observer.update(state.q, state.dq, state.tau)

    def detects(self, state: RobotState) -> bool:
        """Whether the impact is detected at this state (module docstring)."""
        if self.floating:
            return self.detector.update(state.t, *self.generalized(state), self.last)
        return self.detector.update(state.t, self.residual(state))

    def step(self, state: RobotState) -> Command:
        """One period: the detector reads the state's torque residual (the switch to the
        post-impact controller on a detection), then the phase's controller steps on its own
        previous command (the measured q with the commanded dq after a retract's or hold's
        switch; the measured state at the first step) and its Command is returned."""
        if self.phase == APPROACH and self.detects(state):
            self._switch(state)
        if self.last is None:
            q, dq = self.generalized(state)
        elif self.phase in MEASURED_POSITION_PHASES:
            q, dq = self.generalized(state)[0], self.last.dq_cmd
        else:
            q, dq = self.last.q_cmd, self.last.dq_cmd
        self.last = self.controller.step(q, dq)
        if self.phase == APPROACH:
            self.last_approach = self.last
        self._previous_state = state
        return self.last

    def _switch(self, state: RobotState) -> None:
        memory = self.approach.memory
        self.post_impact.reset(memory.q_cmd, memory.dq_cmd)
        self.post_impact.memory = replace(memory)
        self.controller = self.post_impact
        self.phase = self.post_impact.phase = self.config.post_impact.mode
        self.pre_impact_state = self._previous_state

    def contact_speed(self) -> float | None:
        """-n . J(q) dq (m/s) of the last sample before the detection, None without one."""
        state = self.pre_impact_state
        if state is None:
            return None
        normal = np.asarray(self.config.surface.normal, float)
        q, dq = self.generalized(state)
        J = self.robot.terms(q, dq, check_limits=False).J
        return float(-normal @ (J @ dq))
