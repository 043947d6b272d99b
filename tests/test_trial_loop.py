"""The one trial loop of every robot (sim/trial_loop.py): its ending and stop rule, what it logs of
a fixed-base arm and of a robot on held contacts, and the servoed plant's period."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from conftest import JOINTS, g1_model
from impactqp.controller.model.humanoid_stance import STANCES, stance_posture
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError
from impactqp.sim.trial_sources import CartesianApproachCommand
from impactqp.sim.humanoid_scene import build_humanoid_scene
from impactqp.sim.scene import build_scene
from impactqp.sim.servo import StandingSupport
from impactqp.sim.trial_loop import (
    BLEND_CROSSOVER,
    ControllerSource,
    Ending,
    ServoedPlant,
    VelocityCommand,
    any_nonzero,
    run_loop,
)

ROBOT = PandaModel()
GRAVITY = np.array([0.0, 0.0, -9.81])


class StopRecorder:
    """The arm's Cartesian approach as a stopping source: commands zero once stopped, and keeps the
    step at which it was told to stop."""

    def __init__(self, approach):
        self.approach, self.steps, self.stopped_at = approach, 0, None

    def stop(self):
        self.stopped_at = self.steps

    def step(self, q, dq):
        self.steps += 1
        if self.stopped_at is not None:
            return VelocityCommand(np.zeros(JOINTS))
        return self.approach.step(q, dq)


@pytest.fixture(scope="module")
def arm():
    scene = build_scene()
    plant = ServoedPlant(scene, 1e-3)
    q0 = approach_start(ROBOT, PANDA.postures["elbow_up"].q, DEFAULT_WALL, 0.01)
    approach = CartesianApproachCommand(ROBOT, DEFAULT_WALL, 0.2)
    plant.reset(q0, approach.step(q0, np.zeros(JOINTS)).dq_cmd)
    source = StopRecorder(approach)
    return source, plant, run_loop(plant, source, Ending(200, after=30, stop_after=5, hold=True))


def test_the_first_contact_sets_the_stop_and_the_end(arm):
    """k_c is the first control step with a wall force; the source is told to stop at k_c + 5 and
    the trial ends at k_c + 30."""
    source, plant, record = arm
    rows = np.any(record.force.reshape(len(record.t), plant.substeps, 3) != 0.0, axis=2).any(axis=1)
    first = record.first_contact
    assert first is not None and rows[first] and not rows[:first].any()
    assert source.stopped_at == first + 5
    assert len(record.t) == first + 30 and len(record.force) == (first + 30) * plant.substeps
    np.testing.assert_array_equal(record.dq_cmd[first + 5:], 0.0)


def test_the_hold_anchors_the_servo_at_rest_where_the_joints_stopped(arm):
    """The hold puts the servo reference at the joint positions measured at the stop, at rest; the
    zero commands after it keep it there."""
    source, plant, record = arm
    np.testing.assert_array_equal(plant.servo.q_ref, record.q[source.stopped_at])
    np.testing.assert_array_equal(plant.servo.dq_ref, 0.0)


def test_the_arm_has_no_held_contact_log_and_logs_its_joints(arm):
    _, _, record = arm
    assert record.held is None
    assert record.q.shape == record.dq.shape == record.tau.shape == (len(record.t), JOINTS)
    np.testing.assert_allclose(np.diff(record.t), 1e-3)


def test_a_command_of_the_wrong_size_is_an_error():
    scene = build_scene()
    plant = ServoedPlant(scene, 1e-3)
    plant.reset(PANDA.postures["elbow_up"].q, np.zeros(JOINTS))

    class Short:
        def step(self, q, dq):
            return VelocityCommand(np.zeros(JOINTS - 1))

    with pytest.raises(ValueError, match=f"{JOINTS} finite values"):
        run_loop(plant, Short(), Ending(3))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_command_is_an_error(bad):
    scene = build_scene()
    plant = ServoedPlant(scene, 1e-3)
    plant.reset(PANDA.postures["elbow_up"].q, np.zeros(JOINTS))

    class NonFinite:
        def step(self, q, dq):
            command = np.zeros(JOINTS)
            command[-1] = bad
            return VelocityCommand(command)

    with pytest.raises(ValueError, match=f"{JOINTS} finite values"):
        run_loop(plant, NonFinite(), Ending(3))


@settings(max_examples=200)
@given(arrays(np.float64, st.integers(0, 9), elements=st.sampled_from([0.0, -0.0, 1e-300, -2.5, np.nan, np.inf, -np.inf])))
def test_the_compiled_check_is_numpys(x):
    rows = np.resize(x, (len(x) // 3, 3)) if len(x) >= 3 else np.zeros((0, 3))
    assert any_nonzero(rows) == bool(rows.any())


def test_a_period_that_is_not_a_whole_number_of_timesteps_is_bad_input():
    with pytest.raises(BadInputError, match="whole number of timesteps"):
        ServoedPlant(build_scene(), 1.1e-3)


@pytest.fixture(scope="module")
def standing():
    robot = g1_model()
    scene = build_humanoid_scene(robot, wall_x=2.0)
    plant = ServoedPlant(scene, 1e-3, gain=40.0, standing=StandingSupport(robot, scene.base_nq, scene.base_nv))
    q = stance_posture(robot, STANCES["parallel"])
    q[2] -= 0.001
    plant.reset(q)

    class Still:
        def step(self, q, dq):
            return VelocityCommand(np.zeros(robot.n_joints))

    return robot, run_loop(plant, Still(), Ending(100))


def test_a_standing_robot_logs_its_base_first_and_its_held_contacts(standing):
    robot, record = standing
    steps = len(record.t)
    assert record.q.shape == (steps, robot.model.nq) and record.dq.shape == (steps, robot.model.nv)
    assert record.tau.shape == record.dq_cmd.shape == (steps, robot.n_joints)
    np.testing.assert_allclose(np.linalg.norm(record.q[:, 3:robot.base_nq], axis=1), 1.0, atol=1e-9)
    held = record.held
    n = len(robot.description.held_contacts)
    assert held.floor.shape == (steps, 3) and held.feet.shape == (steps, n, 3) and held.soles.shape == (steps, n, 4)
    assert not np.any(record.force)  # the wall is 2 m away
    assert record.first_contact is None


def test_the_floor_impulse_balances_the_momentum_of_a_robot_standing_on_it(standing):
    """m (dc(T) - dc(0)) = floor impulse + m g T (the joint torques are internal, no wall contact);
    the feet carry the weight: the mean vertical floor force is m g."""
    robot, record = standing
    mass = robot.terms(pin.neutral(robot.model)).mass
    com_velocity = [robot.terms(record.q[k]).Jcom @ record.dq[k] for k in (0, len(record.t) - 1)]
    duration = (len(record.t) - 1) * 1e-3
    external = record.held.floor[:-1].sum(axis=0) + mass * GRAVITY * duration
    np.testing.assert_allclose(mass * (com_velocity[1] - com_velocity[0]), external, atol=0.02 * mass * 9.81 * duration)
    assert record.held.floor[:, 2].mean() == pytest.approx(mass * 9.81 * 1e-3, rel=0.05)


class RecordingController:
    """A controller that records the states it is given and commands a fixed (q_cmd, dq_cmd)."""

    def __init__(self, robot, q_cmd, dq_cmd, dt=1e-3):
        self.robot, self.dt, self.given = robot, dt, []
        self.command = type("Command", (), {"q_cmd": q_cmd, "dq_cmd": dq_cmd})()

    def step(self, q, dq):
        self.given.append((np.array(q), np.array(dq)))
        return self.command


@pytest.mark.parametrize("seed", range(3))
def test_the_blended_state_moves_from_the_command_towards_the_measurement_along_the_geodesic(seed):
    """x = x_cmd (+) alpha (x_meas (-) x_cmd), alpha = omega_c dt: the base pose on its manifold
    (a measured pose d away from the command along a constant twist gives the pose alpha d
    along it), the velocities linearly; the first step gets the measured state itself."""
    robot, rng = g1_model(), np.random.default_rng(seed)
    q_cmd = pin.integrate(robot.model, stance_posture(robot, STANCES["parallel"]), 0.05 * rng.normal(size=robot.nv))
    dq_cmd, dq_meas, d = rng.normal(size=robot.nv), rng.normal(size=robot.nv), 0.1 * rng.normal(size=robot.nv)
    q_meas = pin.integrate(robot.model, q_cmd, d)
    controller = RecordingController(robot, q_cmd, dq_cmd)
    source = ControllerSource(controller, "blended")
    source.step(q_meas, dq_meas)
    source.step(q_meas, dq_meas)
    alpha = BLEND_CROSSOVER * controller.dt
    np.testing.assert_array_equal(controller.given[0][0], q_meas)
    np.testing.assert_allclose(pin.difference(robot.model, q_cmd, controller.given[1][0]), alpha * d, atol=1e-12)
    np.testing.assert_allclose(controller.given[1][1], (1 - alpha) * dq_cmd + alpha * dq_meas, atol=1e-12)
    assert 0.0 < alpha < 1.0
