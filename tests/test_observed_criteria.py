"""The failure criteria observed in a simulated trial (sim/observed_criteria.py): the list the
description chooses, each criterion's definition on constructed logs, capture and falling."""

import numpy as np
import pinocchio as pin
import pytest

from impactqp.controller.measured.trial_log import TrialLog
from impactqp.controller.model.humanoid_stance import STANCES, edge_margins, stance_posture, support_polygon
from impactqp.controller.model.max_speed import criteria_of
from impactqp.controller.model.robot import PandaModel, RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.sim.observed_criteria import (
    Observed,
    TrialObservation,
    capture_margin,
    falling_at_the_end,
    first_failure,
    observe,
    observed_criteria,
)

ARM = PandaModel()


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_the_description_chooses_the_criteria_and_the_closed_form_s_names_are_kept(name):
    """Held contacts: the closed form's criteria (joint velocity, foot slip, foot lift, capture)
    and the fall; else the joints' velocity and impulsive torque (the closed form splits the
    velocity into pre- and post-impact)."""
    robot = ROBOTS[name]
    names = [c.name for c in observed_criteria(robot)]
    closed_form = list(criteria_of(robot))
    if robot.held_contacts:
        assert names == [*closed_form, "fell"]
    else:
        assert names == ["joint_velocity", "impulsive_torque"] and "impulsive_torque" in closed_form


def arm_observation(dq: np.ndarray, impulse: np.ndarray, duration: float, watched=None, first: int = 0):
    """An arm's trial log of the joint velocities ``dq`` (steps, joints) at 1 ms."""
    steps = len(dq)
    log = TrialLog(np.arange(steps) * 1e-3, np.zeros_like(dq), dq, np.zeros_like(dq), np.zeros_like(dq))
    q = ARM.description.postures["elbow_up"].q
    watched = np.ones(steps, dtype=bool) if watched is None else watched
    return TrialObservation(ARM, log, watched, first, first, impulse, duration, ARM.terms(q).J, 1e-3)


def test_the_joint_velocity_is_the_largest_ratio_to_the_limit_and_its_onset_the_first_watched_step_above_it():
    rng = np.random.default_rng(3)
    dq = rng.uniform(-0.9, 0.9, (40, ARM.n_joints)) * ARM.dq_max
    dq[25, 4] = 1.5 * ARM.dq_max[4]  # past the limit at step 25
    dq[35, 1] = -2.0 * ARM.dq_max[1]
    dq[5, 2] = 3.0 * ARM.dq_max[2]  # before the watched steps: not seen
    watched = np.arange(40) >= 10
    observed = observe(arm_observation(dq, np.zeros(3), 0.01, watched, first=20))["joint_velocity"]
    assert observed.value == pytest.approx(2.0) and observed.where == ARM.joint_names[1]
    assert observed.failed and observed.onset == pytest.approx(5e-3)


def test_the_impulsive_torque_is_j_transpose_iota_over_the_duration_against_tau_max():
    """max_i |J^T iota|_i / dt / tau_max_i: linear in the impulse, inverse in the duration, and
    failing at the contact exactly above 1."""
    rest = np.zeros((5, ARM.n_joints))
    iota = np.array([-2.0, 0.3, 0.5])
    J = arm_observation(rest, iota, 0.01).contact_jacobian
    expected = max(abs(J[:, i] @ iota) / 0.01 / ARM.tau_max[i] for i in range(ARM.n_joints))
    assert observe(arm_observation(rest, iota, 0.01))["impulsive_torque"].value == pytest.approx(expected, rel=1e-12)
    assert observe(arm_observation(rest, 3.0 * iota, 0.02))["impulsive_torque"].value == pytest.approx(1.5 * expected)
    above = observe(arm_observation(rest, iota * 1.2 / expected, 0.01))
    below = observe(arm_observation(rest, iota * 0.8 / expected, 0.01))
    assert above["impulsive_torque"].failed and above["impulsive_torque"].onset == 0.0
    assert not below["impulsive_torque"].failed and np.isnan(below["impulsive_torque"].onset)
    assert not below["joint_velocity"].failed and np.isnan(below["joint_velocity"].onset)


def test_the_first_failure_is_the_earliest_onset_and_a_tie_goes_to_the_first_in_the_list():
    nan = float("nan")
    criteria = {"a": Observed("a", 2.0, True, 0.004), "b": Observed("b", 0.0, True, 0.002),
                "c": Observed("c", 0.0, True, 0.002), "d": Observed("d", 0.0, False, nan)}
    assert first_failure(criteria) == "b"
    assert first_failure({"d": criteria["d"]}) == ""


def test_capture_margin_agrees_with_the_capture_region_on_constructed_velocities():
    """dc = omega (x - c): the capture point is x, and the margin is x's distance inside the
    support polygon's nearest edge (positive inside, negative outside)."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["wide"])
    polygon = support_polygon(robot, q)
    com = robot.terms(q).com
    omega = np.sqrt(9.81 / com[2])
    heel = polygon[:, 0].min()
    for point in ([heel + 0.01, com[1]], [heel - 0.02, com[1]], polygon.mean(axis=0), [0.5, 0.5]):
        velocity = np.r_[omega * (np.array(point) - com[:2]), 0.0]
        margin = capture_margin(robot, q, velocity)
        assert margin == pytest.approx(edge_margins(polygon, np.array(point)).min(), abs=1e-9)
        assert (margin < 0.0) == (point[0] < heel or point[0] == 0.5)
    assert capture_margin(robot, q, np.zeros(3)) == pytest.approx(edge_margins(polygon, com[:2]).min())


def test_on_the_step_the_capture_margin_is_the_capture_point_s_inside_the_projected_soles():
    """With the left sole on the step the margin is x's distance inside the hull of the corners
    projected from the CoM onto the floor (the raised ones by k = c_z / (c_z - h)), not inside the
    soles' own hull."""
    from impactqp.controller.model.humanoid_stance import convex_hull

    robot = RobotModel("g1")
    stance = STANCES["step"]
    q = stance_posture(robot, stance)
    com = robot.terms(q).com
    corners = robot.sole_corners(q)[:, :2]
    k = com[2] / (com[2] - np.repeat(stance.heights, 4))
    projected = convex_hull(com[:2] + k[:, None] * (corners - com[:2]))
    omega = np.sqrt(9.81 / com[2])
    for point in ([com[0], projected[:, 1].max() - 0.01], [com[0], projected[:, 1].max() + 0.01], [0.5, 0.0]):
        velocity = np.r_[omega * (np.array(point) - com[:2]), 0.0]
        assert capture_margin(robot, q, velocity) == pytest.approx(edge_margins(projected, np.array(point)).min(), abs=1e-4)
    inside_own = np.array([com[0], support_polygon(robot, q)[:, 1].max() + 0.005])  # beyond the soles, within the projection
    assert capture_margin(robot, q, np.r_[omega * (inside_own - com[:2]), 0.0]) > 0.0


def test_a_robot_whose_com_and_capture_point_left_its_feet_is_falling():
    """At the end of a trial the pelvis may still be high while the robot tips over. Standing
    with its CoM over its feet it is not falling, even swaying backwards fast (its capture point
    behind the heels for a moment); the whole robot tipped back about its heels by 25 degrees
    (the CoM behind them) is falling at rest or moving backwards, and not when it moves forwards
    fast enough to bring its capture point back over the feet."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    rest = np.zeros(robot.model.nv)

    def moving(q, vx):  # the whole body translating along world x (base frame velocity, joints still)
        v = rest.copy()
        v[:3] = pin.Quaternion(q[3:robot.base_nq]).matrix().T @ np.array([vx, 0.0, 0.0])
        return v

    np.testing.assert_allclose(robot.terms(q).Jcom @ moving(q, -0.5), [-0.5, 0.0, 0.0], atol=1e-9)
    assert capture_margin(robot, q, np.zeros(3)) > 0.0 > capture_margin(robot, q, np.array([-0.5, 0.0, 0.0]))
    assert not falling_at_the_end(robot, (q, rest)) and not falling_at_the_end(robot, (q, moving(q, -0.5)))

    heel = np.array([support_polygon(robot, q)[:, 0].min(), 0.0, 0.0])
    tip = pin.SE3(pin.utils.rotate("y", -np.radians(25.0)), heel - pin.utils.rotate("y", -np.radians(25.0)) @ heel)
    tipped = q.copy()
    base = tip * pin.XYZQUATToSE3(q[: robot.base_nq])
    tipped[: robot.base_nq] = pin.SE3ToXYZQUAT(base)
    com = robot.terms(tipped).com
    assert com[0] < support_polygon(robot, tipped)[:, 0].min()  # the CoM is behind the heels
    assert falling_at_the_end(robot, (tipped, rest)) and falling_at_the_end(robot, (tipped, moving(tipped, -0.2)))
    omega = np.sqrt(9.81 / com[2])
    middle = support_polygon(robot, tipped)[:, 0].mean()
    forward = omega * (middle - com[0])  # the capture point c + dc / omega over the middle of the feet
    assert not falling_at_the_end(robot, (tipped, moving(tipped, forward)))


def test_a_robot_lying_below_its_feet_has_no_capture_margin_and_is_falling():
    """A state with the CoM at or below the ground (a fallen robot, as a runaway trial can reach)
    is reported, not raised: its capture margin is -inf."""
    robot = RobotModel("g1")
    q = stance_posture(robot, STANCES["parallel"])
    sunk = q.copy()
    sunk[2] -= robot.terms(q).com[2] + 0.05  # the CoM 5 cm below the ground
    assert capture_margin(robot, sunk, np.zeros(3)) == -np.inf
    assert falling_at_the_end(robot, (sunk, np.zeros(robot.model.nv)))


