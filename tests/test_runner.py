"""Closed-loop runner: servo tracking, contact speed, logged force, replay, start state; a
standing robot's trial (the G1 stands the impact, the stop does not jolt its feet)."""

import numpy as np
import pytest

from conftest import JOINTS
from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.measured.impact import measure_impact
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.robot import RobotModel
from impactqp.sim.humanoid_feet import CONE_TOLERANCE, SLIP_SPEED
from impactqp.sim.runner import NORMAL, TrialSpec, run_approach, run_impact_trial, run_trial
from impactqp.sim.trial_sources import CartesianApproachCommand, CommandReplay
from impactqp.sim.scene import build_scene

ROBOT = PandaModel()
SPEED = 0.15


@pytest.fixture(scope="module")
def scene():
    return build_scene()


@pytest.fixture(scope="module")
def log(scene):
    return run_approach(scene, ROBOT, TrialSpec("elbow_right", PANDA.postures["elbow_right"].q, SPEED)).log


def test_log_has_one_sample_per_control_period_and_force_at_the_physics_rate(log, scene):
    n = len(log)
    assert log.t.shape == (n,) and np.allclose(np.diff(log.t), 1e-3)
    for array in (log.q, log.dq, log.tau, log.dq_cmd):
        assert array.shape == (n, JOINTS) and np.all(np.isfinite(array))
    assert log.force.shape == (4 * n, 3) and np.allclose(np.diff(log.force_t), scene.timestep)
    assert log.wall_time > 0.0  # speed goals live in `impactqp bench`, not here


def test_servo_tracks_the_commanded_velocity_before_the_impact(log):
    impact = measure_impact(log)
    free = slice(0, impact.pre_index)
    # dq_cmd_k is the velocity to reach at the end of period k: dq_{k+1}
    error = log.dq[1:][free] - log.dq_cmd[:-1][free]
    assert np.abs(error).max() < 5e-3 * np.abs(log.dq_cmd[free]).max()


def test_contact_speed_is_the_reference_speed(log):
    impact = measure_impact(log)
    v = ROBOT.terms(impact.q_pre, impact.dq_pre).J @ impact.dq_pre
    assert -(DEFAULT_WALL.normal @ v) == pytest.approx(SPEED, rel=0.05)
    # the contact starts when the tip has covered the 2 cm start distance
    assert impact.t_contact_start == pytest.approx(0.02 / SPEED, abs=2e-3)


def test_logged_force_accounts_for_the_momentum_change(log):
    """Generalized momentum balance over the contact phase (first principles):
    M(q+) dq+ - M(q-) dq- = sum_k (tau_k - h_k) dt + J^T iota, with Coriolis terms negligible
    over ~15 ms, so the logged force is the force the robot received."""
    impact = measure_impact(log)
    a, b = impact.pre_index, impact.post_index
    momentum = [ROBOT.terms(log.q[k], log.dq[k]).M @ log.dq[k] for k in (a, b)]
    servo = sum((log.tau[k] - ROBOT.terms(log.q[k], log.dq[k]).h) * 1e-3 for k in range(a, b))
    in_window = (log.force_t >= log.t[a]) & (log.force_t < log.t[b])
    h = log.force_t[1] - log.force_t[0]
    contact = np.zeros(JOINTS)
    for i in np.flatnonzero(in_window):
        k = int(i // 4)
        contact += ROBOT.terms(log.q[k], log.dq[k]).J.T @ log.force[i] * h
    change = momentum[1] - momentum[0]
    assert np.linalg.norm(change - servo - contact) < 0.05 * np.linalg.norm(contact)


def test_force_pushes_the_robot_away_from_the_wall(log):
    n = DEFAULT_WALL.normal
    touching = np.linalg.norm(log.force, axis=1) > 1.0
    assert touching.any()
    normal = log.force[touching] @ n
    tangential = np.linalg.norm(log.force[touching] - np.outer(normal, n), axis=1)
    assert np.all(normal > 0.0)
    assert np.all(tangential <= 0.1123 * normal + 1e-6)  # Coulomb cone, eq. (24)


def test_replaying_the_commands_reproduces_the_trial(log, scene):
    replay = run_trial(scene, CommandReplay(log.dq_cmd, JOINTS), log.q[0], log.dq[0], len(log) * 1e-3)
    np.testing.assert_allclose(replay.q, log.q, atol=1e-12)
    np.testing.assert_allclose(replay.tau, log.tau, atol=1e-9)
    np.testing.assert_allclose(replay.force, log.force, atol=1e-9)


def test_replay_beyond_its_length_is_an_error(scene, log):
    with pytest.raises(IndexError, match="only 3 control steps"):
        run_trial(scene, CommandReplay(log.dq_cmd[:3], JOINTS), log.q[0], log.dq[0], 0.01)


def test_bad_run_arguments_are_rejected(scene, log):
    source = CartesianApproachCommand(ROBOT, DEFAULT_WALL, SPEED)
    with pytest.raises(ValueError, match="whole number of timesteps"):
        run_trial(scene, source, log.q[0], log.dq[0], 0.01, control_period=1.1e-3)
    with pytest.raises(ValueError, match=f"{JOINTS} joint positions"):
        run_trial(scene, source, log.q[0][:-1], log.dq[0], 0.01)


def test_tangential_reference_moves_the_tip_along_the_wall(scene):
    v_t = np.array([0.0, 0.06, 0.0])
    log = run_approach(scene, ROBOT, TrialSpec("elbow_right", PANDA.postures["elbow_right"].q, 0.12, v_t, after_contact=0.05)).log
    impact = measure_impact(log)
    v = ROBOT.terms(impact.q_pre, impact.dq_pre).J @ impact.dq_pre
    np.testing.assert_allclose(v, [0.12, 0.06, 0.0], atol=0.006)


def test_runs_the_impact_aware_qp_controller(scene):
    """run_trial drives any object with step(q, dq) -> .dq_cmd, the QP controller included."""
    controller = build_controller(ControllerConfig.approach(speed=0.15), ROBOT)
    q0 = approach_start(ROBOT, PANDA.postures["elbow_up"].q, DEFAULT_WALL, 0.02)
    log = run_trial(scene, controller, q0, np.zeros(JOINTS), 0.3)
    impact = measure_impact(log)
    v = ROBOT.terms(impact.q_pre, impact.dq_pre).J @ impact.dq_pre
    assert -(DEFAULT_WALL.normal @ v) > 0.05


@pytest.fixture(scope="module")
def standing():
    """A scripted standing trial of the G1: the parallel stance, 0.2 m/s."""
    return run_impact_trial(RobotModel("g1"), STANCES["parallel"], 0.2)


def test_the_wall_pushes_the_hand_back_and_the_robot_stands(standing):
    assert standing.impact.impulse @ NORMAL > 0.0
    assert standing.contact_speed > 0.0
    assert standing.impact.duration > 0.0
    assert not standing.fell and not standing.held.slipped and not standing.held.lifted


def test_a_slow_impact_leaves_the_feet_flat_and_the_com_capturable(standing):
    """0.2 m/s in the parallel stance: the feet stay loaded, inside their cones and still."""
    assert 0.0 < standing.cone_ratio < 1.0 - CONE_TOLERANCE
    assert standing.held.slide_speed < SLIP_SPEED
    assert standing.capture_margin > 0.0


def test_the_stop_does_not_jolt_the_feet():
    """At the stop the wall has stopped the hand while the reference still moves at the approach
    speed; the held servo does not ask for that reference's deceleration in one step, so a trial at
    about 0.5 m/s of contact speed shows no foot onset (with a zero command alone, the left foot
    unloaded at the stop and slipped)."""
    trial = run_impact_trial(RobotModel("g1"), STANCES["wide"], 0.6)
    assert trial.contact_speed > 0.45
    assert trial.failures == ()
