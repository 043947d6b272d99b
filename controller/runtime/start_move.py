"""The move to the start posture before the impact session: a jerk-limited joint trajectory
(Ruckig, the time-optimal trajectory generator franky uses) run by the same loop, watchdog and
command filter as the session.

From rest at q_0 to rest at the target q_T along the straight segment q(s) = q_0 + s (q_T - q_0),
s from 0 to 1: Ruckig plans the time-optimal jerk-limited s(t) with the limits of s that keep
every joint j within ``START_MOVE_SCALE`` of its velocity, acceleration and jerk limits
(|ds/dt| <= scale dq_max_j / |q_T,j - q_0,j|, likewise for the second and third derivatives),
so dq = ds/dt (q_T - q_0). The segment stays inside the joint-limit box, which holds both ends.
The command of cycle k is the velocity at t = k dt: the robot's own
joint controller tracks it, so the final position differs from q_T by the tracking error, which
``final_error`` reports; the session starts from the measured state in any case.

The path is not planned around obstacles. With the session's surface given, the planned path is
checked at ``PATH_SAMPLES`` points: a path whose tool contact point would pass behind the surface
(signed distance < 0) is refused before anything moves; the user brings the robot to the surface's
side first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError

from .interface import RobotState

MOVE_TO_START = "move_to_start"
START_MOVE_SCALE = 0.3
"""Fraction of the datasheet velocity, acceleration and jerk limits for the move to the start."""
PATH_SAMPLES = 200


@dataclass(frozen=True)
class MoveCommand:
    """One command of the move (the loop reads ``dq_cmd`` and ``phase``)."""

    dq_cmd: np.ndarray
    phase: str = MOVE_TO_START


def import_ruckig():
    try:
        import ruckig  # optional: only the robot backends move to a start posture
    except ImportError:
        raise BadInputError("the move to the start posture needs ruckig: pip install -e '.[franka]'") from None
    return ruckig


class StartMove:
    """The move from ``state`` to ``target``: ``duration`` (s) of the planned trajectory; the
    loop's ``start(state)`` plans again from its own first state, ``step(state)`` returns the
    command of the next cycle."""

    def __init__(
        self, target, model: PandaModel, dt: float, state: RobotState, surface: Surface | None = None,
        scale: float = START_MOVE_SCALE,
    ):
        self.target, _ = model.check_state(target)
        self.model = model
        self.dt = float(dt)
        self.scale = float(scale)
        self.trajectory = None
        self.k = 0
        self.start(state)
        if surface is not None:
            self.check_path(surface)

    def check_path(self, surface: Surface) -> None:
        """Bad input when the planned path takes the tool's contact point behind ``surface``."""
        for t in np.linspace(0.0, self.duration, PATH_SAMPLES):
            distance = surface.signed_distance(self.model.contact_point(self.position(t)))
            if distance < 0.0:
                raise BadInputError(
                    f"the move to the start posture would take the tool {-distance * 1e3:.0f} mm behind the surface "
                    f"after {t:.2f} s of its {self.duration:.2f} s: bring the robot in front of the surface first"
                )

    def start(self, state: RobotState) -> None:
        """Plan the move from ``state.q`` (the arm at rest)."""
        ruckig = import_ruckig()
        self.q0 = np.array(state.q, dtype=float)
        self.step_q = self.target - self.q0
        span = np.maximum(np.abs(self.step_q), 1e-12)
        generator, trajectory, parameters = ruckig.Ruckig(1), ruckig.Trajectory(1), ruckig.InputParameter(1)
        parameters.current_position, parameters.target_position = [0.0], [1.0]
        parameters.max_velocity = [float(np.min(self.scale * self.model.dq_max / span))]
        parameters.max_acceleration = [float(np.min(self.scale * self.model.ddq_max / span))]
        parameters.max_jerk = [float(np.min(self.scale * self.model.dddq_max / span))]
        result = generator.calculate(parameters, trajectory)
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise BadInputError(f"no trajectory to the start posture ({result.name})")
        self.trajectory = trajectory
        self.k = 0

    def position(self, t: float) -> np.ndarray:
        """q(t) of the planned move."""
        s, _, _ = self.trajectory.at_time(min(t, self.duration))
        return self.q0 + s[0] * self.step_q

    @property
    def duration(self) -> float:
        return float(self.trajectory.duration)

    def step(self, state: RobotState) -> MoveCommand:
        self.k += 1
        _, ds, _ = self.trajectory.at_time(min(self.k * self.dt, self.duration))
        return MoveCommand(ds[0] * self.step_q)

    def final_error(self, q) -> float:
        """Largest joint distance (rad) of ``q`` from the target."""
        return float(np.max(np.abs(np.asarray(q) - self.target)))
