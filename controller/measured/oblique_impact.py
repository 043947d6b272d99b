"""The oblique impact of one simulated trial: its 3-D impulse split along a wall, the contact's
tangential velocity after the impact and the contact's mode (``docs/frictional-impacts.md``,
"Against MuJoCo").

From a trial log with a per-physics-step contact-force log (``TrialLog.force``: the wall's force
on the robot, world frame, piecewise constant over each step of length h) and the wall's unit
normal n (towards the robot):

Pre-impact state
    (q-, dq-) of :func:`controller.measured.impact.measure_impact` (the samples before the
    contact starts); v- = J(q-) dq-.

Impact window
    From the first step with a non-zero force (s) to the end of compression and restitution
    (e): the first step, at or after the normal force f_n = n^T f has peaked, where f_n is back to
    at most ``force_threshold`` ("separation") or stops decreasing ("force minimum": f_n(e+1) >=
    f_n(e); an arm whose command keeps pressing into the wall never separates, its normal force
    decays to a first local minimum and grows again with the servo's push). A force that has
    neither fallen to the threshold nor stopped decreasing by the log's last step ends the
    window there ("log end": the contact turned into a press without a minimum the log shows,
    the post-impact state read at the log's end is the press's).

Impulse
    iota = h sum_{k=s}^{e} f_k (the exact integral of the piecewise-constant samples), split into
    the normal impulse p_n = n^T iota and the tangential one p_t = (I - n n^T) iota.

Post-impact contact velocity
    v+ = J(q_k) dq_k at the first control sample k at or after the end of step e, and its
    tangential part v_t+ = (I - n n^T) v+.

Least tangential speed
    The smallest distance from 0 of the tangential contact velocity's path over the impact: the
    piecewise-linear path through v_t = (I - n n^T) J(q_k) dq_k at the control samples k from
    the pre-impact state's to the post-impact one's (the straight segment between two samples
    included, :func:`path_least_speed`).

Observed mode (:func:`observed_mode`, the rule of the simulation and of the law alike)
    The contact **stopped** during the impact when its least tangential speed is at most
    ``STICK_SPEED``: then stick when |v_t+| <= ``STICK_SPEED``, else reversal (it stopped, then
    slid off along a direction of its own); slip when it never stopped, however far its
    direction turned. The law's own mode (``FrictionalImpact.mode``) asks the same question,
    "did the contact stop?", at the law's resolution (1e-9 |v-|); MuJoCo's soft friction creeps
    at a fraction of a mm/s where a rigid contact sticks, so the simulation answers it at
    ``STICK_SPEED``, and the law's path (its ``least_tangential_speed``) is read by the same
    rule for the comparison (docs/frictional-impacts.md, "The contact mode's read-out").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.frictional_impact import segment_distance
from impactqp.controller.model.robot import RobotModel

from .impact import DEFAULT_FORCE_THRESHOLD, ImpactNotFoundError, measure_impact
from .trial_log import TrialLog

STICK_SPEED = 2e-3
"""m/s: a tangential contact speed at most this is a contact at rest (module docstring)."""
MODES = ("slip", "stick", "reversal")


def tangential_part(vector: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(I - n n^T) x: the part of ``vector`` in the plane of the unit normal n."""
    return vector - (normal @ vector) * normal


def observed_mode(least_speed: float, post_speed: float, stick_speed: float = STICK_SPEED) -> str:
    """The contact's mode from the least tangential speed along the impact and the post-impact
    one |v_t+| (module docstring, "Observed mode"): "stick", "reversal" or "slip"."""
    if least_speed > stick_speed:
        return "slip"
    return "stick" if post_speed <= stick_speed else "reversal"


def path_least_speed(tangential: np.ndarray) -> float:
    """The smallest distance from 0 of the piecewise-linear path through the rows of
    ``tangential`` (samples x 3; one row: its norm)."""
    if len(tangential) == 1:
        return float(np.linalg.norm(tangential[0]))
    return min(segment_distance(a, b) for a, b in zip(tangential[:-1], tangential[1:]))


@dataclass(frozen=True)
class ObliqueImpact:
    """The measured oblique impact of one trial (module docstring): the physics steps of the
    window (``start``, ``end``, inclusive) and its end rule (``end_rule``: "separation", "force
    minimum" or "log end"), the control samples of the pre- and post-impact states (``pre_index``,
    ``post_index``), the pre-impact joint state (``q_pre``, ``dq_pre``), the impulse on the robot
    (``impulse``, world frame), its normal and tangential parts, the contact velocities before
    and after (``pre_velocity``, ``post_velocity``: J dq, world frame), their tangential parts
    v_t- and v_t+, the least tangential speed along the impact (``least_tangential_speed``) and
    the observed ``mode``."""

    start: int
    end: int
    end_rule: str
    pre_index: int
    post_index: int
    q_pre: np.ndarray
    dq_pre: np.ndarray
    impulse: np.ndarray
    normal_impulse: float
    tangential_impulse: np.ndarray
    pre_velocity: np.ndarray
    post_velocity: np.ndarray
    pre_tangential: np.ndarray
    post_tangential: np.ndarray
    least_tangential_speed: float
    mode: str


def impact_window(normal_force: np.ndarray, threshold: float = DEFAULT_FORCE_THRESHOLD) -> tuple[int, int, str]:
    """(s, e, end rule) of the per-step normal force f_n (module docstring, "Impact window")."""
    touching = np.flatnonzero(normal_force != 0.0)
    if touching.size == 0:
        raise ImpactNotFoundError("the wall's force log holds no contact")
    start = int(touching[0])
    last = len(normal_force) - 1
    k = start
    while k < last and normal_force[k + 1] > normal_force[k]:
        k += 1  # to the peak
    while k < last and threshold < normal_force[k] and normal_force[k + 1] < normal_force[k]:
        k += 1
    if normal_force[k] <= threshold:
        return start, k, "separation"
    return start, k, "force minimum" if k < last else "log end"


def measure_oblique_impact(log: TrialLog, robot: RobotModel, normal: np.ndarray,
                           force_threshold: float = DEFAULT_FORCE_THRESHOLD) -> ObliqueImpact:
    """The oblique impact of ``log`` against the wall of unit normal ``normal`` (towards the
    robot) for ``robot``'s contact Jacobian (module docstring); raises ``ImpactNotFoundError``
    without a force log or a contact."""
    if not log.has_force:
        raise ImpactNotFoundError("an oblique impact is measured from the wall's force log")
    normal = np.asarray(normal, dtype=float)
    pre = measure_impact(log, force_threshold=force_threshold)
    step = float(log.force_t[1] - log.force_t[0])
    start, end, rule = impact_window(log.force @ normal, force_threshold)
    impulse = log.force[start:end + 1].sum(axis=0) * step
    ends_at = log.force_t[end] + step
    post = min(int(np.searchsorted(log.t, ends_at - 1e-9 * step)), len(log.t) - 1)
    pre_velocity = robot.terms(pre.q_pre).J @ pre.dq_pre
    post_velocity = robot.terms(log.q[post]).J @ log.dq[post]
    pre_tangential, post_tangential = tangential_part(pre_velocity, normal), tangential_part(post_velocity, normal)
    path = [tangential_part(robot.terms(log.q[k]).J @ log.dq[k], normal) for k in range(pre.pre_index + 1, post)]
    least = path_least_speed(np.array([pre_tangential, *path, post_tangential]))
    return ObliqueImpact(
        start=start, end=end, end_rule=rule, pre_index=pre.pre_index, post_index=post, q_pre=pre.q_pre,
        dq_pre=pre.dq_pre, impulse=impulse, normal_impulse=float(normal @ impulse),
        tangential_impulse=tangential_part(impulse, normal), pre_velocity=pre_velocity,
        post_velocity=post_velocity, pre_tangential=pre_tangential, post_tangential=post_tangential,
        least_tangential_speed=least, mode=observed_mode(least, float(np.linalg.norm(post_tangential))),
    )
