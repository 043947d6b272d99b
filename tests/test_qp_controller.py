"""ImpactAwareController: hard constraints, closed-form solutions, the maximum feasible speed,
command continuity, the stacked QP data of a cycle and its active constraints; on the standing
G1 (a floating base on held contacts): every row, the feet held, the impact rows binding, a
closed approach and the brake of unusable states."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import whole_body_states as g1
from qp_states import DT, NORMAL, approach_controller, random_feasible_state, surface_ahead
from reference.qp import reference_active_constraints, reference_integrate_command

from conftest import JOINTS
from impactqp.constraints import ControlCycle, jump_model_names
from impactqp.controller.config import ControllerConfig, TaskConfig, build_controller
from impactqp.controller.model.inverse_kinematics import approach_start
from impactqp.controller.model.humanoid_stance import STANCES
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS
from impactqp.controller.model.max_speed import Setting, approach_direction, closed_form_max_speed
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp import ImpactAwareController
from impactqp.controller.qp.command import command_limits
from impactqp.controller.qp.cycle_kernels import COMMAND_ROWS, integrate_command
from impactqp.tasks import DampingTask, FrameTask, PostureTask


def check_hard_constraints(robot, controller, command, q, dq, previous_ddq, models, restitution):
    tol = 1e-6
    terms = robot.terms(q, dq)
    ddq, dq_cmd = command.ddq, command.dq_cmd
    assert np.all(np.isfinite(ddq)) and np.all(np.isfinite(dq_cmd)) and np.all(np.isfinite(command.q_cmd))
    assert np.allclose(dq_cmd, dq + ddq * DT, atol=1e-12)
    assert np.all(np.abs(ddq) <= robot.ddq_max + tol)
    assert np.all(np.abs(ddq - previous_ddq) <= robot.dddq_max * DT + tol)
    assert np.all(np.abs(dq_cmd) <= robot.dq_max + tol)
    assert np.all(command.q_cmd >= robot.q_min - tol) and np.all(command.q_cmd <= robot.q_max + tol)
    assert np.all(np.abs(terms.M @ ddq + terms.h) <= robot.tau_max + tol)
    surface = controller.impact.surface
    for name in models:
        prediction = jump_model(name).predict(terms, surface.normal, terms.J @ dq_cmd, restitution)
        assert np.all(np.abs(dq_cmd + prediction.dq_jump) <= robot.dq_max + tol), name
        assert np.all(np.abs(terms.J.T @ prediction.impulse) / 0.015 <= robot.tau_max + tol), name


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["crb", "gm", "classical", "robust"]), st.sampled_from([0.0, 0.5]))
def test_solution_satisfies_every_hard_constraint(robot, seed, jump, restitution):
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, jump_model_names(jump), restitution)
    controller = approach_controller(robot, q, speed=rng.uniform(0.0, 2.0), jump=jump, restitution=restitution)
    command = controller.step(q, dq)
    assert command.status == "ok", command.message
    check_hard_constraints(robot, controller, command, q, dq, np.zeros(JOINTS), jump_model_names(jump), restitution)
    assert np.allclose(command.predicted_post_impact_velocity, command.dq_cmd + command.predicted_jump)


def test_unconstrained_qp_is_the_weighted_least_squares_solution(robot):
    q = PANDA.postures["elbow_up"].q
    dq = np.full(JOINTS, 0.01)
    terms = robot.terms(q, dq)
    tasks = [
        FrameTask(terms.contact_point + [0.0, 0.001, 0.0], stiffness=1.0, position_weight=3.0, orientation_weight=0.5),
        PostureTask(q + 0.001, stiffness=1.0, weight=0.1),
        DampingTask(robot.nv, gain=0.5, weight=1e-3),
    ]
    all_limits = build_controller(ControllerConfig(tasks=[TaskConfig("damping")]), robot).constraints
    controller = ImpactAwareController(robot, tasks, all_limits, DT)
    command = controller.step(q, dq)
    assert command.status == "ok" and command.active_constraints == []
    rows = [t.compute(terms) for t in tasks]
    sqrt_w = np.sqrt(np.concatenate([r.weight for r in rows]))
    A = np.vstack([r.A for r in rows]) * sqrt_w[:, None]
    b = np.concatenate([r.b for r in rows]) * sqrt_w
    expected = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.allclose(command.ddq, expected, atol=1e-6 * (1.0 + np.abs(expected).max()))


def max_feasible_speed_by_bisection(robot, terms, model, restitution=0.0, impact_duration=0.015):
    """Largest v with dq- = v d satisfying (a) |dq-| <= dq_max, (b) |dq+| <= dq_max and
    (c) |J^T iota| / delta_t <= tau_max, found by bisection on the predictor itself."""

    def feasible(v):
        pre = v * approach_direction(robot, terms, NORMAL)
        prediction = model.predict(terms, NORMAL, terms.J @ pre, restitution)
        return (
            np.all(np.abs(pre) <= robot.dq_max)
            and np.all(np.abs(pre + prediction.dq_jump) <= robot.dq_max)
            and np.all(np.abs(terms.J.T @ prediction.impulse) / impact_duration <= robot.tau_max)
        )

    low, high = 0.0, 10.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if feasible(middle) else (low, middle)
    return low


@pytest.mark.parametrize("posture", sorted(PANDA.postures))
@pytest.mark.parametrize("jump", ["crb", "gm"])
def test_commanded_speed_settles_at_the_maximum_feasible_speed(robot, posture, jump):
    """Asked for 2 m/s at a posture (kept fixed), the commanded contact speed settles at the
    posture's maximum feasible speed."""
    q = PANDA.postures[posture].q
    controller = approach_controller(robot, q, speed=2.0, jump=jump)
    dq = np.zeros(JOINTS)
    for _ in range(800):
        command = controller.step(q, dq)
        assert command.status == "ok", command.message
        dq = command.dq_cmd
    terms = robot.terms(q)
    speed = float(-NORMAL @ (terms.J @ command.dq_cmd))
    expected = max_feasible_speed_by_bisection(robot, terms, jump_model(jump))
    assert speed == pytest.approx(expected, rel=0.02)
    assert any(name.endswith(f"[{jump}]") or name == "joint_velocity_limit" for name in command.active_constraints)


@pytest.mark.parametrize("posture", ["elbow_up", "elbow_left"])
def test_fast_approach_from_afar_stays_within_the_impact_limits(robot, posture):
    """Asked for 2 m/s from 30 cm away, the controller speeds up while the wall is far and slows
    down to the impact-feasible speed as it enters the activation zone: every command keeps the
    limits, and the contact speed is at most the crb maximum at the contact posture."""
    wall = PANDA.postures[posture].surface
    q = approach_start(robot, PANDA.postures[posture].q, wall, 0.3)
    controller = build_controller(ControllerConfig.approach(wall, speed=2.0), robot)
    dq, previous, top_speed = np.zeros(JOINTS), np.zeros(JOINTS), 0.0
    for _ in range(3000):
        command = controller.step(q, dq)
        assert np.all(np.isfinite(command.dq_cmd)) and np.all(np.abs(command.dq_cmd) <= robot.dq_max)
        assert np.all(np.abs(command.ddq - previous) <= robot.dddq_max * DT + 1e-6)
        previous, q, dq = command.ddq, command.q_cmd, command.dq_cmd
        terms = robot.terms(q, dq)
        top_speed = max(top_speed, float(-wall.normal @ (terms.J @ dq)))
        if wall.signed_distance(terms.contact_point) < 0.002:
            break
    else:
        pytest.fail("the tool never reached the wall")
    contact_speed = float(-wall.normal @ (terms.J @ dq))
    assert top_speed > 1.5 * contact_speed  # it went faster while the wall was far
    limit = closed_form_max_speed(robot, terms, wall.normal, Setting("crb"))
    assert contact_speed <= 1.02 * limit.speed
    assert controller.fallback_count <= 10


def test_closed_loop_commands_are_continuous(robot):
    """Kinematic closed loop towards the wall: every command keeps the acceleration and jerk
    limits relative to the previous one, across a reference step."""
    q = PANDA.postures["elbow_up"].q.copy()
    config = ControllerConfig.approach(surface_ahead(robot, q, 0.08), speed=0.05)
    controller = build_controller(config, robot)
    dq, previous = np.zeros(JOINTS), np.zeros(JOINTS)
    for k in range(400):
        if k == 150:
            controller.tasks[0].reference_velocity = -1.5 * NORMAL  # step of the reference
        command = controller.step(q, dq)
        assert not command.is_fallback, command.message
        assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-6)
        assert np.all(np.abs(command.ddq - previous) <= robot.dddq_max * DT + 1e-6)
        previous, q, dq = command.ddq, command.q_cmd, command.dq_cmd
    assert command.impact_constraints_active


@pytest.mark.parametrize("written", [np.nan, 1e9, 0.0])
def test_what_the_caller_writes_into_a_command_does_not_reach_the_next_one(robot, written):
    """Two controllers stepped on one kinematic loop; the caller then overwrites every array of
    one's command (ddq, dq_cmd, q_cmd, the prediction): at the next states both command the same."""
    q = PANDA.postures["elbow_up"].q.copy()
    config = ControllerConfig.approach(surface_ahead(robot, q, 0.08), speed=0.3)
    mine, other = build_controller(config, robot), build_controller(config, robot)
    dq = np.zeros(JOINTS)
    for _ in range(20):
        command, twin = mine.step(q, dq), other.step(q, dq)
        q, dq = twin.q_cmd.copy(), twin.dq_cmd.copy()
    for array in (command.ddq, command.dq_cmd, command.q_cmd, command.predicted_jump, command.predicted_post_impact_velocity):
        array[:] = written
    for _ in range(5):
        command, twin = mine.step(q, dq), other.step(q, dq)
        assert command.status == twin.status == "ok"
        np.testing.assert_array_equal(command.dq_cmd, twin.dq_cmd)
        np.testing.assert_array_equal(command.q_cmd, twin.q_cmd)
        q, dq = twin.q_cmd.copy(), twin.dq_cmd.copy()


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 2.0))
def test_closed_loop_command_sequence_keeps_every_limit(robot, seed, speed):
    """A kinematic closed loop (q, dq <- q_cmd, dq_cmd) from a random state and target: every
    command is finite, ddq = (dq_cmd - dq)/dt, and every consecutive pair keeps the velocity,
    acceleration and jerk limits (the velocity limit is a row of the QP, nothing is clipped
    after it)."""
    rng = np.random.default_rng(seed)
    span = robot.q_max - robot.q_min
    q = robot.q_min + span * rng.uniform(0.2, 0.8, JOINTS)
    dq = rng.uniform(-0.9, 0.9, JOINTS) * robot.dq_max
    config = ControllerConfig.approach(surface_ahead(robot, q, rng.uniform(0.02, 0.2)), speed)
    controller = build_controller(config, robot)
    controller.reset(q, dq)
    controller.tasks[0].reference_velocity = speed * rng.uniform(-1.0, 1.0, 3)
    previous = np.zeros(JOINTS)
    for _ in range(150):
        command = controller.step(q, dq)
        for value in (command.ddq, command.dq_cmd, command.q_cmd):
            assert np.all(np.isfinite(value))
        assert np.allclose(command.ddq, (command.dq_cmd - dq) / DT, atol=1e-6)
        assert np.all(np.abs(command.dq_cmd) <= robot.dq_max + 1e-9)
        assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-6)
        assert np.all(np.abs(command.ddq - previous) <= robot.dddq_max * DT + 1e-6)
        previous, q, dq = command.ddq, command.q_cmd, command.dq_cmd


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jump=st.sampled_from(["crb", "gm", "classical", "robust"]))
def test_stacked_qp_data_are_the_rows_of_every_task_and_constraint(robot, seed, jump):
    """The controller writes every row in place into one stacked QP; it must equal what each
    task and constraint gives on its own (``compute``): H = sum A^T W A, g = -sum A^T W b, the
    box = the intersection of the clipped boxes, and each constraint's rows (relaxed where the
    class says so)."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, jump_model_names(jump), 0.0)
    controller = approach_controller(robot, q, jump=jump, solver="daqp")
    controller.step(q, dq)  # a first cycle, so the memory holds a non-zero acceleration
    terms = robot.terms(q, dq)
    controller._cycle.advance(controller.memory.ddq, controller.ddq_max, controller._jerk_step)
    controller._assemble(terms, controller._cycle)
    p = controller.problem

    H, g = np.zeros((JOINTS, JOINTS)), np.zeros(JOINTS)
    for task in controller.tasks:
        rows = task.compute(terms)
        H += rows.A.T @ (rows.weight[:, None] * rows.A)
        g -= rows.A.T @ (rows.weight * rows.b)
    np.testing.assert_allclose(p.H, H, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(p.g, g, rtol=1e-12, atol=1e-9)

    cycle = ControlCycle.after(controller.memory.ddq, DT, robot.ddq_max, robot.dddq_max)
    boxes = [c.compute(terms, cycle) for c in controller.box_constraints]
    np.testing.assert_allclose(p.lb, np.max([b.lower for b in boxes], axis=0), atol=1e-12)
    np.testing.assert_allclose(p.ub, np.min([b.upper for b in boxes], axis=0), atol=1e-12)
    row_cycle = ControlCycle(DT, p.lb.copy(), p.ub.copy(), cycle.horizon)
    for constraint, rows in zip(controller.row_constraints, controller.layout.row_slices):
        expected = constraint.compute(terms, row_cycle)
        np.testing.assert_allclose(p.C[rows], expected.C, atol=1e-12, err_msg=constraint.name)
        np.testing.assert_allclose(p.l[rows], expected.lower, rtol=1e-12, atol=1e-9, err_msg=constraint.name)
        np.testing.assert_allclose(p.u[rows], expected.upper, rtol=1e-12, atol=1e-9, err_msg=constraint.name)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jump=st.sampled_from(["crb", "gm", "robust"]))
def test_compiled_active_set_equals_the_numpy_reference(robot, seed, jump):
    """The active constraints of the cycle (compiled, from the gaps of the feasibility check, in
    one call with it) agree with their plain-numpy statement, on the solution and on perturbed
    points around it; the check's violation is the problem's."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, jump_model_names(jump), 0.0)
    controller = approach_controller(robot, q, jump=jump, solver="daqp")
    command = controller.step(q, dq)
    problem = controller.problem
    tolerance = 10.0 * controller.feasibility_tolerance
    for x in (command.ddq, command.ddq + rng.normal(0.0, 1e-3, JOINTS), command.ddq + rng.normal(0.0, 1.0, JOINTS)):
        violation = controller._checked(x)
        assert violation == problem.violation(x)
        expected = reference_active_constraints(controller.layout, controller._box_bounds, problem, tolerance, x)
        assert controller._active_constraints() == expected


# ---------------------------------------------------------------- the standing G1
G1_SETTINGS = settings(max_examples=12, deadline=None)
G1_TOLERANCE = 1e-6


def impact_rows(c):
    return [x for x in c.layout.row_constraints if x.relaxed]


@G1_SETTINGS
@given(g1.standing_states(), st.sampled_from(HELD_CONTACT_METHODS), st.floats(0.0, 1.0), st.booleans())
def test_every_row_holds_and_the_feet_do_not_accelerate_at_the_solution(state, method, speed, always):
    name, q, v = state
    c = g1.controller(name, method=method, speed=speed, always_active=always)
    c.reset(q, v)
    command = c.step(q, v)
    assert not command.is_fallback, command.message
    dv = command.ddq
    assert c.problem.violation(dv) <= G1_TOLERANCE
    terms = g1.robot().terms(q, v)
    np.testing.assert_allclose(terms.held_jacobian @ dv + terms.held_drift, 0.0, atol=G1_TOLERANCE)
    # the joints' own limits, the impact rows as the constraints write them
    base = g1.robot().base_nv
    joints = dv[base:]
    assert np.all(np.abs(joints) <= g1.robot().ddq_max + G1_TOLERANCE)
    assert np.all(np.abs(command.dq_cmd[base:]) <= g1.robot().dq_max)
    for constraint in impact_rows(c):
        C, lower, upper = np.zeros((constraint.rows, g1.robot().nv)), np.zeros(constraint.rows), np.zeros(constraint.rows)
        constraint.compute_into(terms, c._row_cycle, C, lower, upper)
        if np.all(lower <= 0.0) and np.all(upper >= 0.0):  # the state keeps them: they are not relaxed
            assert np.all(C @ dv <= upper + G1_TOLERANCE) and np.all(C @ dv >= lower - G1_TOLERANCE)
    np.testing.assert_allclose(command.dq_cmd, v + dv * c.dt)


@G1_SETTINGS
@given(st.sampled_from(sorted(STANCES)), st.sampled_from(HELD_CONTACT_METHODS), st.floats(2.0, 3.0))
def test_impact_rows_bind_when_the_approach_speed_is_pushed_up(name, method, asked):
    """The hand moves at just below the highest speed s* the impact rows allow (bisection on
    the rows at v = s d, dv = 0, d the least-norm feet-held approach at 1 m/s) and the task asks
    for more: an impact row is active at the solution, and the commanded velocity keeps the
    predicted post-impact joint velocities within their limits. The balance tasks (CoM, torso)
    are off, so that the impact rows alone keep the post-impact CoM velocity capturable."""
    c = g1.controller(name, method=method, speed=asked, always_active=True, com_weight=0.0, torso_weight=0.0)
    q = g1.stance(name)
    unit = g1.approach_velocity(q, 1.0)

    def holds(s):
        terms = g1.robot().terms(q, s * unit)
        for x in impact_rows(c):
            C, lower, upper = np.zeros((x.rows, g1.robot().nv)), np.zeros(x.rows), np.zeros(x.rows)
            x.compute_into(terms, c._cycle, C, lower, upper)
            if np.any(upper < 0.0) or np.any(lower > 0.0):
                return False
        return True

    low, high = 0.0, asked
    for _ in range(40):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if holds(middle) else (low, middle)
    assert 0.1 < low < 0.99 * asked
    v = 0.999 * low * unit
    c.reset(q, v)
    command = c.step(q, v)
    assert not command.is_fallback, command.message
    assert any(x.name in command.active_constraints for x in impact_rows(c)), command.active_constraints
    maps = jump_model(method).unit_matrices(g1.robot().terms(q, command.dq_cmd), g1.NORMAL, 0.0)
    post = command.dq_cmd + maps.jump_matrix @ command.dq_cmd
    assert np.all(np.abs(post[g1.robot().base_nv:]) <= g1.robot().dq_max + 1e-9)


def test_closed_loop_approach_keeps_the_feet_and_reaches_the_asked_speed():
    c = g1.controller("parallel", gap=0.2, speed=0.2)
    q, v = g1.stance("parallel"), np.zeros(g1.robot().nv)
    c.reset(q, v)
    feet = g1.robot().frame_placements(q)
    for _ in range(300):
        command = c.step(q, v)
        assert not command.is_fallback, command.message
        q, v = command.q_cmd, command.dq_cmd
    terms = g1.robot().terms(q, v)
    assert -g1.NORMAL @ terms.J @ v == pytest.approx(0.2, abs=0.02)
    for name, placement in g1.robot().frame_placements(q).items():
        if name in feet and "ankle" in name:
            np.testing.assert_allclose(placement.translation, feet[name].translation, atol=1e-3)


def test_unusable_states_brake_the_joints_with_the_feet_held():
    c = g1.controller("wide")
    q = g1.stance("wide")
    v = g1.approach_velocity(q, 0.5)
    with pytest.raises(BadInputError):
        c.step(q[:-1], v)  # no previous command to stand in
    c.reset(q, v)
    first = c.step(q, v)
    for bad_q, bad_v, status in (
        (q, np.full(g1.robot().nv, np.nan), "fallback_invalid_state"),
        (q, np.r_[np.zeros(g1.robot().base_nv), 1e3 * np.ones(g1.robot().n_joints)], "fallback_invalid_state"),
    ):
        command = c.step(bad_q, bad_v)
        assert command.status == status and np.all(np.isfinite(command.q_cmd))
        terms = g1.robot().terms(first.q_cmd if np.isnan(bad_v).any() else bad_q, first.dq_cmd if np.isnan(bad_v).any() else bad_v)
        Jf, base = terms.held_jacobian, slice(0, g1.robot().base_nv)
        np.testing.assert_allclose(Jf[:, base].T @ (Jf @ command.dq_cmd), 0.0, atol=1e-9)  # the feet as still as they can be
        np.testing.assert_allclose(command.dq_cmd, terms.dq + command.ddq * c.dt, atol=1e-9)


def test_velocities_measured_past_their_limits_cycle_after_cycle_build_up_no_base_twist():
    """A kinematic loop whose measured joint rates are 20 % past their limits at every cycle
    (alternate signs): every cycle is a fallback, none raises, the joints stay within their
    limits and the base's commanded twist stays bounded by the joints' rates through the feet."""
    c = g1.controller("parallel")
    robot = g1.robot()
    over = 1.2 * robot.dq_max * np.where(np.arange(robot.n_joints) % 2 == 0, 1.0, -1.0)
    q, dq = g1.stance("parallel").copy(), np.zeros(robot.nv)
    twists = []
    for _ in range(120):
        measured = dq.copy()
        measured[robot.base_nv:] += over
        command = c.step(q, measured)
        assert command.status == "fallback_invalid_state"
        assert np.all(np.isfinite(command.q_cmd)) and np.all(np.abs(command.dq_cmd[robot.base_nv:]) <= robot.dq_max)
        twists.append(np.abs(command.dq_cmd[:robot.base_nv]).max())
        q, dq = command.q_cmd.copy(), command.dq_cmd.copy()
    assert max(twists[60:]) <= 1.5 * max(twists[:60])


# ---------------------------------------------------------------- the impact brake
def measured_state_loop(robot_name: str, speed: float, duration: float = 0.9):
    """The loop a pink or mink user writes: read the measured state, step, send dq_cmd, on the
    MuJoCo robot hitting the wall of its default posture at ``speed`` asked; (model, commands,
    measured velocities, statuses, contact time)."""
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.sim.scene import build_scene
    from impactqp.sim.sim_backend import SimRobot

    choice = RobotChoice.of(robot_name)
    model = choice.shared_model
    posture = choice.posture(choice.robot.default_posture)
    config = ControllerConfig.approach(posture.surface, speed, robot=robot_name)
    controller = build_controller(config, model)
    wall = config.surface.surface()
    q0 = approach_start(model, posture.q, wall, 0.05)
    robot = SimRobot(build_scene(wall, robot=choice.robot, tool=choice.tool), q0, np.zeros(model.nv), config.dt)
    commands, velocities, statuses = [], [], []
    for _ in range(int(round(duration / config.dt))):
        state = robot.read()
        command = controller.step(state.q, state.dq)
        robot.write(command.dq_cmd)
        commands.append(command.dq_cmd)
        velocities.append(state.dq)
        statuses.append(command.status)
    t, force = robot.force_log()
    touching = np.linalg.norm(force, axis=1) > 1.0
    contact = float(t[np.argmax(touching)]) if touching.any() else None
    return model, np.array(commands), np.array(velocities), statuses, contact


@pytest.mark.parametrize("robot_name", ["panda", "fr3"])
@pytest.mark.parametrize("speed", [0.3, 0.5])
def test_a_measured_state_loop_brakes_after_the_impact_and_never_holds_a_limit(robot_name, speed):
    """Fed the measured state through the impact, the commands never sit at a velocity limit
    for more than 20 ms, every measured |dq| is back under half its limit within 300 ms of the
    first contact and stays there, and the controller brakes its commands to rest."""
    dt = 0.001
    model, commands, velocities, statuses, contact = measured_state_loop(robot_name, speed)
    assert contact is not None, "the robot never reached the wall"
    at_limit = np.abs(commands) >= model.dq_max * (1.0 - 1e-9)
    longest = max((len(run) for column in at_limit.T for run in "".join("1" if x else "0" for x in column).split("0")), default=0)
    assert longest * dt <= 0.020
    after = int(round((contact + 0.3) / dt))
    assert np.all(np.abs(velocities[after:]) < 0.5 * model.dq_max)
    assert statuses[-1] == "impact_brake" and np.all(commands[-1] == 0.0)
    braking = statuses.index("impact_brake")
    assert contact <= braking * dt <= contact + 0.02  # noticed at the impact, not before
    steps = np.diff(commands[braking - 1:], axis=0) / dt
    assert np.all(np.abs(steps) <= model.ddq_max * (1.0 + 1e-9))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([0.1, 1.0, 50.0]))
def test_a_fixed_bases_command_kernel_is_its_numpy_twin(robot, seed, scale):
    """``integrate_command`` (dq_cmd and q_cmd within the limits, the predicted jump A dq_cmd and
    the post-impact velocity at dq_cmd, in one pass) gives its plain-numpy twin's values, clipped
    or not."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.q_min, robot.q_max)
    dq = rng.uniform(-1.0, 1.0, robot.nv) * robot.dq_max
    ddq, A = scale * rng.normal(size=robot.nv) / DT, rng.normal(size=(robot.nv, robot.nv))
    out = np.empty((COMMAND_ROWS, robot.nv))
    limits = command_limits(robot, robot.ddq_max, robot.dddq_max * DT)
    clipped = integrate_command(q, dq, ddq, DT, limits, A, out)
    *expected, expected_clipped = reference_integrate_command(q, dq, ddq, DT, robot, A)
    assert clipped == expected_clipped
    for row, twin in zip(out, expected):
        np.testing.assert_allclose(row, twin, rtol=1e-12, atol=1e-12)
