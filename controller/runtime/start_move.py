"""The move to the start posture before the impact session: jerk-limited joint segments (Ruckig,
the time-optimal trajectory generator franky uses) run by the same loop, watchdog and command
filter as the session.

**Timing.** Each segment goes from rest at q_a to rest at q_b along the straight joint segment
q(s) = q_a + s (q_b - q_a), s from 0 to 1: Ruckig plans the time-optimal jerk-limited s(t) with
the limits of s that keep every joint j within ``START_MOVE_SCALE`` of its velocity,
acceleration and jerk limits (|ds/dt| <= scale dq_max_j / |q_b,j - q_a,j|, likewise for the
second and third derivatives), so dq = ds/dt (q_b - q_a). Velocity and acceleration are zero at
both ends of a segment, so the segments join without a jump of either. Every segment stays
inside the joint-limit box, which holds its ends. The command of cycle k is the velocity at
t = k dt: the robot's own joint controller tracks it, so the final position differs from the
target by the tracking error, which ``final_error`` reports; the session starts from the
measured state in any case.

**Path in front of the surface.** With the session's surface given, the path keeps the tool's
clearance c(q) >= ``START_CLEARANCE``: c is the smallest signed distance to the surface (n . (x -
p), positive on the robot's side) of the tool's contact point and of every point of the tool's
geometry (``Sphere.lowest``, ``Pad.lowest``: with the tool frame at (R, o), min over the
geometry of n . (o + R y - p) = n . (o - p) + lowest(R^T n)). A segment is checked at samples
at most ``PATH_STEP`` rad apart on every joint. The paths tried, in order, until one keeps the
clearance: the straight segment to the target; then the retreat of the tool along the normal by
each distance of ``RETREATS`` (the via point: the contact frame's pose at the start moved by
d n, orientation kept, solved by the damped least-squares inverse kinematics from the start
posture), then the segment from it to the target. No such path: bad input that names the
clearance reached and the margin, before anything moves (also when the target or the start
itself is closer than the margin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from impactqp.controller.model.inverse_kinematics import APPROACH_STOP, pose, solve
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.validation import BadInputError

from .interface import RobotState

MOVE_TO_START = "move_to_start"
START_MOVE_SCALE = 0.3
"""Fraction of the datasheet velocity, acceleration and jerk limits for the move to the start."""
START_CLEARANCE = 0.02
"""m: the smallest distance the tool (its contact point and its geometry) keeps in front of the
surface along the move to the start."""
RETREATS = (0.05, 0.1, 0.15, 0.2, 0.3)
"""m: the retreats along the surface normal tried as the via point of the move, in order."""
PATH_STEP = 2e-3
"""rad: the largest step of any joint between two checked samples of a segment."""


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


def tool_clearance(model: PandaModel, surface: Surface, q) -> float:
    """c(q) of the module docstring (m): the contact point's signed distance, or the tool
    geometry's smallest one when it is smaller."""
    frame = model.contact_frame(q)
    distance = surface.signed_distance(frame.translation)
    tool = model.tool
    if tool is None:
        return distance
    origin = frame.translation - frame.rotation @ tool.contact_point  # the contact frame turns with the tool's
    return min(distance, surface.signed_distance(origin) + tool.geometry.lowest(frame.rotation.T @ surface.normal))


def segment_clearance(model: PandaModel, surface: Surface, a: np.ndarray, b: np.ndarray) -> float:
    """The smallest c along the straight joint segment from ``a`` to ``b``, sampled at most
    ``PATH_STEP`` rad apart on every joint."""
    samples = max(2, math.ceil(float(np.max(np.abs(b - a))) / PATH_STEP) + 1)
    return min(tool_clearance(model, surface, a + s * (b - a)) for s in np.linspace(0.0, 1.0, samples))


def retreat(model: PandaModel, surface: Surface, q0: np.ndarray, distance: float) -> np.ndarray | None:
    """The posture with the contact frame of ``q0`` moved by ``distance`` along the surface
    normal, orientation kept (inverse kinematics from ``q0``); None when out of reach."""
    start = model.contact_frame(q0)
    target = pin.SE3(start.rotation, start.translation + distance * surface.normal)
    solved = solve(model, pose(model, target), q0, APPROACH_STOP)
    return solved.q if solved.reachable else None


@dataclass(frozen=True)
class StartPath:
    """The via points of the move (none: the straight segment), the retreat that gave them (m; 0:
    none) and the smallest clearance along the path (m)."""

    vias: tuple[np.ndarray, ...]
    retreat: float
    clearance: float


def path_in_front(model: PandaModel, surface: Surface, q0: np.ndarray, target: np.ndarray, margin: float) -> StartPath:
    """The first path of the module docstring whose clearance is at least ``margin``; bad input
    when none is."""
    mm = margin * 1e3
    for where, q in (("the start posture", target), ("the robot", q0)):
        c = tool_clearance(model, surface, q)
        if c < margin:
            raise BadInputError(
                f"{where} puts the tool {c * 1e3:.0f} mm in front of the surface, within the margin of {mm:.0f} mm "
                "the move to the start keeps (START_CLEARANCE): bring the robot farther in front of the surface first"
            )
    best = segment_clearance(model, surface, q0, target)
    if best >= margin:
        return StartPath((), 0.0, best)
    for distance in RETREATS:
        via = retreat(model, surface, q0, distance)
        if via is None:
            continue
        c = min(segment_clearance(model, surface, q0, via), segment_clearance(model, surface, via, target))
        if c >= margin:
            return StartPath((via,), distance, c)
        best = max(best, c)
    raise BadInputError(
        f"no path to the start posture keeps the tool {mm:.0f} mm in front of the surface (START_CLEARANCE): "
        f"the best one tried (straight, or through a retreat of up to {max(RETREATS, default=0.0) * 1e3:.0f} mm along the normal) "
        f"comes within {best * 1e3:.0f} mm of it; bring the robot farther in front of the surface first"
    )


@dataclass(frozen=True)
class Segment:
    """One rest-to-rest segment: from ``q`` by ``step`` along the Ruckig profile ``trajectory``
    of s, starting at ``t0`` (s) of the move."""

    q: np.ndarray
    step: np.ndarray
    trajectory: object
    t0: float

    @property
    def t1(self) -> float:
        return self.t0 + float(self.trajectory.duration)


def segment(ruckig, model: PandaModel, scale: float, q: np.ndarray, target: np.ndarray, t0: float) -> Segment:
    """The time-optimal segment from ``q`` to ``target`` within ``scale`` of the limits."""
    step = target - q
    span = np.maximum(np.abs(step), 1e-12)
    generator, trajectory, parameters = ruckig.Ruckig(1), ruckig.Trajectory(1), ruckig.InputParameter(1)
    parameters.current_position, parameters.target_position = [0.0], [1.0]
    parameters.max_velocity = [float(np.min(scale * model.dq_max / span))]
    parameters.max_acceleration = [float(np.min(scale * model.ddq_max / span))]
    parameters.max_jerk = [float(np.min(scale * model.dddq_max / span))]
    result = generator.calculate(parameters, trajectory)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise BadInputError(f"no trajectory to the start posture ({result.name})")
    return Segment(q, step, trajectory, t0)


class StartMove:
    """The move from ``state`` to ``target``: ``duration`` (s) of the planned trajectory; with
    ``surface``, through the via point of ``path`` (module docstring) that keeps the tool
    ``clearance`` (m) in front of it. The loop's ``start(state)`` plans the timing again from its
    own first state, ``step(state)`` returns the command of the next cycle."""

    def __init__(
        self, target, model: PandaModel, dt: float, state: RobotState, surface: Surface | None = None,
        scale: float = START_MOVE_SCALE, clearance: float = START_CLEARANCE,
    ):
        self.target, _ = model.check_state(target)
        self.model = model
        self.dt = float(dt)
        self.scale = float(scale)
        q0 = np.array(state.q, dtype=float)
        self.path = StartPath((), 0.0, math.nan) if surface is None else path_in_front(model, surface, q0, self.target, clearance)
        self.segments: list[Segment] = []
        self.k = 0
        self.start(state)

    def start(self, state: RobotState) -> None:
        """Plan the move from ``state.q`` (the arm at rest) through the path's via points."""
        ruckig = import_ruckig()
        self.q0 = np.array(state.q, dtype=float)
        points = [self.q0, *self.path.vias, self.target]
        self.segments, t0 = [], 0.0
        for a, b in zip(points[:-1], points[1:]):
            self.segments.append(segment(ruckig, self.model, self.scale, a, b, t0))
            t0 = self.segments[-1].t1
        self.k = 0

    def at(self, t: float) -> tuple[Segment, float, float]:
        """The segment running at ``t`` and its s, ds/dt there."""
        t = min(t, self.duration)
        part = next((p for p in self.segments if t <= p.t1), self.segments[-1])
        s, ds, _ = part.trajectory.at_time(t - part.t0)
        return part, s[0], ds[0]

    def position(self, t: float) -> np.ndarray:
        """q(t) of the planned move."""
        part, s, _ = self.at(t)
        return part.q + s * part.step

    @property
    def duration(self) -> float:
        return self.segments[-1].t1

    def step(self, state: RobotState) -> MoveCommand:
        self.k += 1
        part, _, ds = self.at(self.k * self.dt)
        return MoveCommand(ds * part.step)

    def final_error(self, q) -> float:
        """Largest joint distance (rad) of ``q`` from the target."""
        return float(np.max(np.abs(np.asarray(q) - self.target)))
