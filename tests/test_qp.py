"""ImpactAwareController: hard constraints, closed-form solutions, solver agreement, the
maximum feasible speed, command continuity and the fallback."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.config import ControllerConfig, TaskConfig, build_controller
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.max_speed import approach_direction, closed_form_max_speed
from impactqp.controller.model.postures import POSTURES, Surface
from impactqp.constraints import ControlCycle
from impactqp.controller.qp import Command, DaqpSolver, ImpactAwareController, QuadprogSolver
from impactqp.controller.model.robot import SingularPostureError
from impactqp.constraints import jump_model_names
from impactqp.controller.qp import available_backends, interval_conflicts
from impactqp.tasks import DampingTask, FrameTask, PostureTask

NORMAL = np.array([-1.0, 0.0, 0.0])
DT = 0.001


def surface_ahead(robot, q, gap):
    tip = robot.contact_point(q)
    return Surface(tip - gap * NORMAL, NORMAL)


def approach_controller(robot, q, speed=2.0, jump="crb", solver="proxqp", restitution=0.0):
    config = ControllerConfig.approach(
        surface_ahead(robot, q, 0.05), speed, jump_model=jump, restitution=restitution,
        solver=solver, always_active=True, posture_weight=0.0,
    )
    controller = build_controller(config, robot)
    return controller


def state_satisfies_the_limits(robot, terms, models, restitution):
    """The state itself (ddq = 0) keeps every hard limit, the impact ones included."""
    if np.any(np.abs(terms.dq) > 0.9 * robot.dq_max):
        return False
    for name in models:
        prediction = jump_model(name).predict(terms, NORMAL, terms.J @ terms.dq, restitution)
        if np.any(np.abs(terms.dq + prediction.dq_jump) > 0.9 * robot.dq_max):
            return False
        if np.any(np.abs(terms.J.T @ prediction.impulse) / 0.015 > 0.9 * robot.tau_max):
            return False
    return bool(np.all(np.abs(terms.h) < 0.9 * robot.tau_max))


def random_feasible_state(robot, rng, models, restitution):
    """Random posture, random approach velocity, shrunk until the state keeps every limit."""
    span = robot.q_max - robot.q_min
    while True:
        q = robot.q_min + span * rng.uniform(0.15, 0.85, 7)
        try:
            terms = robot.terms(q)
        except SingularPostureError:
            continue
        dq = rng.uniform(0.0, 0.3) * approach_direction(terms, NORMAL) + rng.uniform(-0.05, 0.05, 7)
        for _ in range(20):
            if state_satisfies_the_limits(robot, robot.terms(q, dq), models, restitution):
                return q, dq
            dq = 0.5 * dq


def check_hard_constraints(robot, controller, command, q, dq, previous_ddq, models, restitution, tol=1e-6):
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
    check_hard_constraints(robot, controller, command, q, dq, np.zeros(7), jump_model_names(jump), restitution)
    assert np.allclose(command.predicted_post_impact_velocity, command.dq_cmd + command.predicted_jump)


def test_unconstrained_qp_is_the_weighted_least_squares_solution(robot):
    q = POSTURES["elbow_up"].q
    dq = np.full(7, 0.01)
    terms = robot.terms(q, dq)
    tasks = [
        FrameTask(terms.contact_point + [0.0, 0.001, 0.0], stiffness=1.0, position_weight=3.0, orientation_weight=0.5),
        PostureTask(q + 0.001, stiffness=1.0, weight=0.1),
        DampingTask(gain=0.5, weight=1e-3),
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


@pytest.mark.parametrize("posture", sorted(POSTURES))
def test_solver_backends_agree(robot, posture):
    """Same QPs, same answers; three cycles, so that the warm-started proxqp must notice that
    the jerk box moved (its stale multipliers would otherwise pass the residual checks)."""
    q = POSTURES[posture].q
    terms = robot.terms(q)
    dq = 0.12 * approach_direction(terms, NORMAL)  # near the speed limit: the impact rows bind
    results = {}
    for solver in available_backends():
        controller = approach_controller(robot, q, solver=solver)
        controller.reset(q, dq)
        commands = [controller.step(q, dq) for _ in range(3)]
        assert all(c.status == "ok" for c in commands), solver
        results[solver] = np.array([c.ddq for c in commands])
    reference = results["daqp"]
    for solver, ddq in results.items():
        assert np.allclose(ddq, reference, atol=1e-5), solver


def max_feasible_speed_by_bisection(robot, terms, model, restitution=0.0, impact_duration=0.015):
    """Largest v with dq- = v d satisfying (a) |dq-| <= dq_max, (b) |dq+| <= dq_max and
    (c) |J^T iota| / delta_t <= tau_max, found by bisection on the predictor itself."""

    def feasible(v):
        pre = v * approach_direction(terms, NORMAL)
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


@pytest.mark.parametrize("posture", sorted(POSTURES))
@pytest.mark.parametrize("jump", ["crb", "gm"])
def test_commanded_speed_settles_at_the_maximum_feasible_speed(robot, posture, jump):
    """Asked for 2 m/s at a posture (kept fixed), the commanded contact speed settles at the
    posture's maximum feasible speed."""
    q = POSTURES[posture].q
    controller = approach_controller(robot, q, speed=2.0, jump=jump)
    dq = np.zeros(7)
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
    from impactqp.controller.model.inverse_kinematics import approach_start

    wall = POSTURES[posture].surface
    q = approach_start(robot, POSTURES[posture].q, wall, 0.3)
    controller = build_controller(ControllerConfig.approach(wall, speed=2.0), robot)
    dq, previous, top_speed = np.zeros(7), np.zeros(7), 0.0
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
    limit = closed_form_max_speed(robot, terms, wall.normal, jump_model("crb"))
    assert contact_speed <= 1.02 * limit.speed
    assert controller.fallback_count <= 10


def test_closed_loop_commands_are_continuous(robot):
    """Kinematic closed loop towards the wall: every command keeps the acceleration and jerk
    limits relative to the previous one, across a reference step."""
    q = POSTURES["elbow_up"].q.copy()
    config = ControllerConfig.approach(surface_ahead(robot, q, 0.08), speed=0.05)
    controller = build_controller(config, robot)
    dq, previous = np.zeros(7), np.zeros(7)
    for k in range(400):
        if k == 150:
            controller.tasks[0].reference_velocity = -1.5 * NORMAL  # step of the reference
        command = controller.step(q, dq)
        assert not command.is_fallback, command.message
        assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-6)
        assert np.all(np.abs(command.ddq - previous) <= robot.dddq_max * DT + 1e-6)
        previous, q, dq = command.ddq, command.q_cmd, command.dq_cmd
    assert command.impact_constraints_active


def assert_safe_fallback(robot, controller, command, status, previous_ddq=np.zeros(7)):
    assert isinstance(command, Command)
    assert command.status == status and command.is_fallback
    for value in (command.ddq, command.dq_cmd, command.q_cmd, command.predicted_jump):
        assert np.all(np.isfinite(value))
    assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-9)
    assert np.all(np.abs(command.ddq - previous_ddq) <= robot.dddq_max * DT + 1e-9)
    assert np.all(np.abs(command.dq_cmd) <= robot.dq_max)
    assert np.all(command.q_cmd >= robot.q_min) and np.all(command.q_cmd <= robot.q_max)


def test_nan_state_gives_the_fallback(robot):
    q = POSTURES["elbow_up"].q
    controller = approach_controller(robot, q)
    first = controller.step(q, np.zeros(7))
    command = controller.step(np.full(7, np.nan), np.zeros(7))
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state", first.ddq)
    assert controller.fallback_count == 1
    fresh = approach_controller(robot, q)
    assert_safe_fallback(robot, fresh, fresh.step(q, [np.nan] * 7), "fallback_invalid_state")
    assert_safe_fallback(robot, fresh, fresh.step([1.0, 2.0], None), "fallback_invalid_state")
    assert fresh.fallback_count == 2


def test_state_outside_the_limits_gives_the_fallback(robot):
    q = POSTURES["elbow_up"].q
    controller = approach_controller(robot, q)
    outside = q.copy()
    outside[3] = robot.q_max[3] + 0.05
    command = controller.step(outside, np.zeros(7))
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state")
    assert command.violated_constraints == ["joint_position_limit"]
    too_fast = np.zeros(7)
    too_fast[0] = 1.1 * robot.dq_max[0]
    command = controller.step(q, too_fast)
    assert_safe_fallback(robot, controller, command, "fallback_invalid_state", controller.memory.ddq)
    assert command.violated_constraints == ["joint_velocity_limit"]
    assert command.dq_cmd[0] < too_fast[0]  # braking
    assert controller.fallback_count == 2


def test_infeasible_request_gives_the_fallback_and_names_the_conflict(robot):
    """Approaching at 0.6 m/s with the impact constraints on: no acceleration of one cycle can
    bring the impulsive torque within its limit."""
    q = POSTURES["elbow_up"].q
    controller = approach_controller(robot, q)
    dq = 0.6 * approach_direction(robot.terms(q), NORMAL)
    command = controller.step(q, dq)
    assert_safe_fallback(robot, controller, command, "fallback_infeasible")
    assert "impulsive_torque[crb]" in command.violated_constraints
    assert len(command.violated_constraints) >= 2  # with a limit on ddq: acceleration or torque
    assert np.linalg.norm(command.dq_cmd) < np.linalg.norm(dq)
    assert controller.fallback_count == 1


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 2.0))
def test_closed_loop_command_sequence_keeps_every_limit(robot, seed, speed):
    """A kinematic closed loop (q, dq <- q_cmd, dq_cmd) from a random state and target: every
    command is finite, ddq = (dq_cmd - dq)/dt, and every consecutive pair keeps the velocity,
    acceleration and jerk limits (the velocity limit is a row of the QP, nothing is clipped
    after it)."""
    rng = np.random.default_rng(seed)
    span = robot.q_max - robot.q_min
    q = robot.q_min + span * rng.uniform(0.2, 0.8, 7)
    dq = rng.uniform(-0.9, 0.9, 7) * robot.dq_max
    config = ControllerConfig.approach(surface_ahead(robot, q, rng.uniform(0.02, 0.2)), speed)
    controller = build_controller(config, robot)
    controller.reset(q, dq)
    controller.tasks[0].reference_velocity = speed * rng.uniform(-1.0, 1.0, 3)
    previous = np.zeros(7)
    for _ in range(150):
        command = controller.step(q, dq)
        for value in (command.ddq, command.dq_cmd, command.q_cmd):
            assert np.all(np.isfinite(value))
        assert np.allclose(command.ddq, (command.dq_cmd - dq) / DT, atol=1e-6)
        assert np.all(np.abs(command.dq_cmd) <= robot.dq_max + 1e-9)
        assert np.all(np.abs(command.ddq) <= robot.ddq_max + 1e-6)
        assert np.all(np.abs(command.ddq - previous) <= robot.dddq_max * DT + 1e-6)
        previous, q, dq = command.ddq, command.q_cmd, command.dq_cmd


def test_the_irreducible_conflict_is_computed_on_demand(robot):
    """``step`` names a bounded conflicting set; the irreducible one (deletion filter) is
    computed only when asked for, after the fact."""
    q = POSTURES["elbow_up"].q
    controller = approach_controller(robot, q)
    assert controller.conflicting_constraints() == []  # no infeasible cycle yet
    command = controller.step(q, 0.6 * approach_direction(robot.terms(q), NORMAL))
    assert command.status == "fallback_infeasible"
    irreducible = controller.conflicting_constraints()
    assert "impulsive_torque[crb]" in irreducible and len(irreducible) >= 2
    assert set(irreducible) <= {c.name for c in controller.constraints}


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

    H, g = np.zeros((7, 7)), np.zeros(7)
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
    for constraint, rows in zip(controller.row_constraints, controller._row_slices):
        expected = constraint.compute(terms, row_cycle)
        np.testing.assert_allclose(p.C[rows], expected.C, atol=1e-12, err_msg=constraint.name)
        np.testing.assert_allclose(p.l[rows], expected.lower, rtol=1e-12, atol=1e-9, err_msg=constraint.name)
        np.testing.assert_allclose(p.u[rows], expected.upper, rtol=1e-12, atol=1e-9, err_msg=constraint.name)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_the_confirming_solver_agrees_with_daqp(robot, seed):
    """quadprog, the second opinion behind daqp, finds the same optimum on feasible QPs of the
    controller, and both call a QP with an empty row interval infeasible."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, ("crb",), 0.0)
    controller = approach_controller(robot, q, solver="daqp")
    controller.step(q, dq)
    problem = controller.problem
    rows = problem.C.shape[0]
    status_daqp, x_daqp = DaqpSolver(rows).solve(problem)
    status_quadprog, x_quadprog = QuadprogSolver(rows).solve(problem)
    assert status_daqp == status_quadprog
    if status_daqp == "solved":
        np.testing.assert_allclose(x_quadprog, x_daqp, atol=1e-6)
    infeasible = problem.copy()
    infeasible.l[0], infeasible.u[0] = 1.0, -1.0  # l > u: no ddq can satisfy row 0
    assert DaqpSolver(rows).solve(infeasible)[0] == "infeasible"
    assert QuadprogSolver(rows).solve(infeasible)[0] == "infeasible"


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jump=st.sampled_from(["crb", "gm", "robust"]))
def test_compiled_check_and_active_set_equal_the_numpy_reference(robot, seed, jump):
    """The feasibility check and the active constraints of the cycle (compiled) agree with
    their plain-numpy statements, on the solution and on perturbed points around it."""
    rng = np.random.default_rng(seed)
    q, dq = random_feasible_state(robot, rng, jump_model_names(jump), 0.0)
    controller = approach_controller(robot, q, jump=jump, solver="daqp")
    command = controller.step(q, dq)
    problem = controller.problem
    for x in (command.ddq, command.ddq + rng.normal(0.0, 1e-3, 7), command.ddq + rng.normal(0.0, 1.0, 7)):
        fast = problem.violation(x)
        gaps = (problem.lower_gap.copy(), problem.upper_gap.copy())
        assert fast == pytest.approx(problem.reference_violation(x), rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(gaps[0], problem.lower_gap, rtol=1e-12, atol=1e-12)
        problem.violation(x)
        assert controller._active_constraints(x) == controller.reference_active_constraints(x)
    assert problem.violation(np.full(7, np.nan)) == np.inf


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), jump=st.sampled_from(["crb", "gm", "robust"]), speed=st.floats(0.3, 0.8))
def test_compiled_conflict_and_braking_equal_the_numpy_reference(robot, seed, jump, speed):
    """On an infeasible cycle (a fast approach with the impact constraints on), the compiled
    interval test names the same conflicting set as its numpy statement, and the compiled
    braking command equals its numpy statement from random states and previous accelerations."""
    rng = np.random.default_rng(seed)
    q = POSTURES["elbow_up"].q
    controller = approach_controller(robot, q, jump=jump)
    dq = speed * approach_direction(robot.terms(q), NORMAL)
    command = controller.step(q, dq)
    if command.status == "fallback_infeasible":
        problem = controller.problem
        fast, reference = np.zeros_like(controller._active_flags), np.ones_like(controller._active_flags)
        args = (controller._box_bounds, problem.lb, problem.ub, problem.C, problem.l, problem.u, controller._row_ends)
        assert interval_conflicts(*args, fast) == controller.reference_interval_conflicts(reference)
        np.testing.assert_array_equal(fast, reference)
        assert command.violated_constraints == controller._conflict_names(reference, True)
    for _ in range(5):
        q = robot.q_min + (robot.q_max - robot.q_min) * rng.uniform(-0.1, 1.1, 7)
        dq = rng.uniform(-1.2, 1.2, 7) * robot.dq_max
        controller.memory.ddq = rng.uniform(-1.0, 1.0, 7) * robot.ddq_max
        expected = controller.reference_braking_command(q, dq)
        command = controller._fallback(q, dq, "fallback_infeasible", [], "")
        for fast, reference in zip((command.ddq, command.dq_cmd, command.q_cmd), expected):
            np.testing.assert_allclose(fast, reference, rtol=1e-12, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_interval_test_flags_exactly_the_rows_no_point_of_the_box_satisfies(seed):
    """The span of C_i x over the box is attained at its vertices: a row is flagged exactly when
    every one of the 2^7 vertices gives C_i x above u_i or every one below l_i."""
    rng = np.random.default_rng(seed)
    lb = rng.uniform(-2.0, 0.0, 7)
    ub = lb + rng.uniform(0.0, 2.0, 7)
    C = rng.normal(size=(6, 7))
    centre = rng.normal(0.0, 4.0, 6)
    l, u = centre - rng.uniform(0.0, 1.0, 6), centre + rng.uniform(0.0, 1.0, 6)
    vertices = np.array(np.meshgrid(*zip(lb, ub), indexing="ij")).reshape(7, -1)
    values = C @ vertices
    unreachable = (values > u[:, None]).all(axis=1) | (values < l[:, None]).all(axis=1)
    row_ends = np.array([2, 3, 6])  # three constraints of 2, 1 and 3 rows
    box_bounds = np.vstack([lb, ub, lb - 1.0, ub + 1.0])  # box 0 sets [lb, ub], box 1 does not
    flags = np.zeros(5, dtype=np.bool_)
    assert interval_conflicts(box_bounds, lb, ub, C, l, u, row_ends, flags)
    expected = [unreachable[0:2].any(), unreachable[2:3].any(), unreachable[3:6].any()]
    np.testing.assert_array_equal(flags, [True, False, *expected])
    assert not interval_conflicts(box_bounds, ub + 1.0, lb, C, l, u, row_ends, flags)
