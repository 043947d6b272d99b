"""The compiled cycle plan (``controller.qp.cycle_plan``): the QP of its one compiled call is the
generic assembly's (task by task, constraint by constraint) and its numpy twin's, on random
states; the controllers it serves and those it leaves to the generic assembly; one compiled
signature of each kernel of an arm's cycle, whatever the robot and the number of impacts."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import JOINTS
from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.qp import ImpactAwareController
from impactqp.controller.qp.cycle_plan import KERNEL_KINDS, CycleBuffers, CyclePlan, planned_rows
from impactqp.controller.qp.whole_body_plan import WHOLE_BODY_KINDS, WholeBodyPlan
from impactqp.controller.model.tool_postures import tool_posture
from impactqp.constraints import AccelerationLimit, ExpectedImpact, PostImpactVelocityLimit
from impactqp.controller.model.friction_pyramid import FrictionRows
from impactqp.tasks import DampingTask, FrameTask, PostureTask, SurfaceOffsetTask
from qp_states import surface_ahead
from reference.qp import reference_planned_qp

SETTINGS = {"crb": (0.0, False), "robust": (0.0, False), "friction4": (0.3, False), "always": (0.0, True)}


def start(robot) -> np.ndarray:
    return tool_posture(robot, robot.description.default_posture).q


def setting_controller(robot, setting: str) -> ImpactAwareController:
    """An approach controller with every limit on, the wall 5 cm ahead of the default posture:
    the crb rows, the robust three-model rows, the crb rows with a 4-edge friction pyramid, or
    the crb rows always active."""
    friction, always = SETTINGS[setting]
    q = start(robot)
    config = ControllerConfig.approach(
        surface_ahead(robot, q, 0.05), 0.5, jump_model="robust" if setting == "robust" else "crb",
        friction=friction, always_active=always,
    )
    return build_controller(config, robot)


def random_cycle(robot, controller, rng):
    """The terms of a random state and the cycle after a random previous acceleration."""
    q = robot.q_min + (robot.q_max - robot.q_min) * rng.uniform(0.1, 0.9, JOINTS)
    dq = rng.uniform(-0.8, 0.8, JOINTS) * robot.dq_max
    terms = robot.terms(q, dq, check_limits=False)
    for task in controller.tasks:
        task.reset(terms)
    cycle = controller._cycle
    cycle.advance(rng.uniform(-1.0, 1.0, JOINTS) * controller.ddq_max, controller.ddq_max, controller._jerk_step)
    return terms, cycle


def generic_qp(controller, terms, cycle) -> tuple:
    """The QP of the generic assembly, copied."""
    controller._assemble_tasks(terms)
    consistent = controller._assemble_constraints(terms, cycle)
    p = controller.problem
    return p.H.copy(), p.g.copy(), p.lb.copy(), p.ub.copy(), p.C.copy(), p.l.copy(), p.u.copy(), consistent


def planned_qp(controller, terms, cycle) -> tuple:
    """The QP of the compiled plan, copied."""
    consistent = controller._plan.fill(terms, cycle)
    p = controller.problem
    return p.H.copy(), p.g.copy(), p.lb.copy(), p.ub.copy(), p.C.copy(), p.l.copy(), p.u.copy(), consistent


def assert_same_qp(first: tuple, second: tuple, tolerance: float) -> None:
    assert first[-1] == second[-1]
    for a, b in zip(first[:-1], second[:-1]):
        assert np.array_equal(np.isinf(a), np.isinf(b))
        finite = np.isfinite(a)
        assert np.allclose(a[finite], b[finite], rtol=tolerance, atol=tolerance)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), setting=st.sampled_from(sorted(SETTINGS)))
def test_the_plan_writes_the_generic_qp_and_its_numpy_twin(robot, seed, setting):
    rng = np.random.default_rng(seed)
    controller = setting_controller(robot, setting)
    assert controller._plan is not None
    terms, cycle = random_cycle(robot, controller, rng)
    planned = planned_qp(controller, terms, cycle)
    assert_same_qp(planned, generic_qp(controller, terms, cycle), 1e-12)
    assert_same_qp(planned, reference_planned_qp(controller.tasks, controller.layout, terms, cycle), 1e-9)


def test_an_assigned_parameter_reaches_the_plan(robot):
    """A task's parameter set by assignment after the plan was packed is in the next cycle's QP."""
    rng = np.random.default_rng(3)
    controller = setting_controller(robot, "crb")
    terms, cycle = random_cycle(robot, controller, rng)
    before = planned_qp(controller, terms, cycle)
    approach, posture = controller.tasks[0], controller.tasks[1]
    approach.reference_velocity = np.array([0.1, -0.2, 0.3])
    posture.weight = 10.0 * posture.weight
    controller.constraints[-1].row_scale = controller.constraints[-1].row_scale  # any assignment repacks
    after = planned_qp(controller, terms, cycle)
    assert not np.allclose(before[1], after[1])
    assert_same_qp(after, generic_qp(controller, terms, cycle), 1e-12)


def test_commands_with_and_without_the_plan_are_equal(robot):
    """The closed loop's commands, from the plan and from the generic assembly (same states)."""
    planned, generic = (setting_controller(robot, "crb") for _ in range(2))
    generic._plan = None
    q, dq, active = start(robot), np.zeros(JOINTS), []
    for _ in range(400):
        command, reference = planned.step(q, dq), generic.step(q, dq)
        assert command.status == reference.status
        assert np.allclose(command.dq_cmd, reference.dq_cmd, rtol=0.0, atol=1e-12)
        assert np.allclose(command.q_cmd, reference.q_cmd, rtol=0.0, atol=1e-12)
        assert np.allclose(command.predicted_jump, reference.predicted_jump, rtol=0.0, atol=1e-12)
        q, dq = command.q_cmd, command.dq_cmd
        active.append(command.impact_constraints_active)
    assert any(active)  # the impact rows were on in some cycles


def test_a_task_without_a_kernel_of_the_plan_leaves_the_generic_assembly(robot):
    task = SurfaceOffsetTask([-1.0, 0.0, 0.0], [0.5, 0.0, 0.5], 0.02)
    assert type(task) not in WHOLE_BODY_KINDS
    controller = ImpactAwareController(robot, [task, DampingTask(JOINTS)], [AccelerationLimit()], 0.001)
    assert controller._plan is None
    planned = ImpactAwareController(robot, [PostureTask(joints=JOINTS), DampingTask(JOINTS)], [AccelerationLimit()], 0.001)
    assert type(planned._plan) is CyclePlan


def test_a_frame_task_takes_the_whole_body_plan(robot):
    """A frame task has no kernel of the arm's plan: its controller takes the whole-body plan."""
    assert FrameTask not in KERNEL_KINDS
    controller = ImpactAwareController(robot, [FrameTask(), DampingTask(JOINTS)], [AccelerationLimit()], 0.001)
    assert type(controller._plan) is WholeBodyPlan


def test_one_and_three_impact_models_share_the_plans_compiled_signature(robot):
    """The plan's call is of flat arrays only: controllers with one (crb) and three (robust)
    expected impacts, with and without friction rows, run the same compiled ``planned_rows``."""
    for setting in ("crb", "robust", "friction4"):
        controller = setting_controller(robot, setting)
        q, dq = start(robot), np.zeros(JOINTS)
        for _ in range(3):
            command = controller.step(q, dq)
            q, dq = command.q_cmd, command.dq_cmd
    assert len(planned_rows.signatures) == 1


ARM_CYCLES = textwrap.dedent(
    """
    import json, sys
    sys.path[:0] = sys.argv[1:2]
    import compile_once
    compile_once.install()
    import numpy as np
    from numba.core.registry import CPUDispatcher
    from impactqp.controller.config import ControllerConfig, build_controller
    from impactqp.controller.model.postures import Surface
    from impactqp.controller.model.robot import RobotModel
    from impactqp.controller.model.tool_postures import tool_posture

    for name in ("panda", "fr3", "ur5"):
        robot = RobotModel(name)
        posture = tool_posture(robot, robot.description.default_posture)
        normal = posture.surface.normal
        surface = Surface(robot.contact_point(posture.q) - 0.05 * normal, normal)
        for options in ({}, {"jump_model": "robust"}, {"friction": 0.3}, {"always_active": True}):
            controller = build_controller(ControllerConfig.approach(surface, 0.5, **options), robot)
            q, dq = posture.q, None  # the description's read-only posture, at rest
            for _ in range(20):
                command = controller.step(q, dq)
                q, dq = command.q_cmd, command.dq_cmd
    kernels = {
        f"{module.__name__}.{name}": len(kernel.signatures)
        for module in list(sys.modules.values()) if getattr(module, "__name__", "").startswith("impactqp")
        for name, kernel in vars(module).items()
        if isinstance(kernel, CPUDispatcher) and kernel.py_func.__module__ == module.__name__
    }
    print(json.dumps(kernels))
    """
)


def test_each_kernel_of_the_arms_cycles_has_one_compiled_signature():
    """In a fresh process, the cycles of the three arms (crb, robust, friction rows, always
    active; from a read-only posture at rest, then their own commands) compile each kernel they
    reach once: the same argument types whatever the robot, the caller's arrays or the impacts."""
    tests = str(Path(__file__).parent)
    child = subprocess.run([sys.executable, "-c", ARM_CYCLES, tests], capture_output=True, text=True, check=True)
    kernels = json.loads(child.stdout.splitlines()[-1])
    reached = {name: count for name, count in kernels.items() if count}
    assert "impactqp.controller.qp.cycle_plan.planned_rows" in reached
    assert {name: count for name, count in reached.items() if count != 1} == {}


def test_the_cycle_buffers_are_views_tiling_one_array():
    """``CycleBuffers.empty``'s arrays (and its QP's) are views of its one array, each entry of it
    in exactly one of them, in ``cycle_buffer_views``' order."""
    n, task_rows, rows, boxes = 4, 5, 3, 2
    buffers = CycleBuffers.empty(n, task_rows, rows, boxes)
    p = buffers.problem
    views = [np.stack([buffers.reachable_lower, buffers.reachable_upper]), buffers.task_A, buffers.task_b, buffers.task_w,
             p.H, p.g, p.C, p.bounds, buffers.box_bounds]
    shapes = [(2, n), (task_rows, n), (task_rows,), (task_rows,), (n, n), (n,), (rows, n), (2, n + rows), (2 * boxes, n)]
    assert [view.shape for view in views] == shapes
    for k, view in enumerate(views[1:], start=1):
        view[...] = k
    buffers.reachable_lower[:], buffers.reachable_upper[:] = 0.0, 0.0
    expected = np.concatenate([np.full(int(np.prod(shape)), float(k)) for k, shape in enumerate(shapes)])
    np.testing.assert_array_equal(buffers.data, expected)
    assert np.shares_memory(p.lower, buffers.data) and np.shares_memory(p.lb, buffers.data)


def test_impacts_of_different_friction_rows_leave_the_generic_assembly(robot):
    """The plan stacks its impacts' edges in one array: impacts with different numbers of edges
    (none and a 4-edge pyramid) leave the generic assembly; the first alone takes the plan."""
    q = start(robot)
    surface = surface_ahead(robot, q, 0.05)
    impacts = [ExpectedImpact(surface, "crb"), ExpectedImpact(surface, "gm", friction=FrictionRows(0.3))]
    rows = [PostImpactVelocityLimit(impact, robot.dq_max) for impact in impacts]
    controller = ImpactAwareController(robot, [PostureTask(joints=JOINTS), DampingTask(JOINTS)], rows, 0.001)
    assert controller._plan is None
    same = ImpactAwareController(robot, [PostureTask(joints=JOINTS), DampingTask(JOINTS)], rows[:1], 0.001)
    assert type(same._plan) is CyclePlan


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), setting=st.sampled_from(["crb", "always", "friction4", "robust"]))
def test_the_plan_updates_its_impacts_as_they_would_themselves(robot, seed, setting):
    """The plan's kernel updates its impacts (``stacked_updates``): after its fill each impact's
    A, P, G, its friction pyramid's edge maps (to 1e-12 of their largest entry: the same kernels
    compiled into different callers, M^-1 by another Cholesky) and its activation are those a twin
    impact (same surface, model, rule and friction rows) computes itself at the same terms; an
    impact's rule assigned later reaches the next fill."""
    rng = np.random.default_rng(seed)
    controller = setting_controller(robot, setting)
    plan = controller._plan
    assert plan.updates_impacts
    terms, cycle = random_cycle(robot, controller, rng)
    twins = [ExpectedImpact(i.surface, i.name, i.restitution, i.rule, friction=i.friction) for i in plan.impacts]
    plan.fill(terms, cycle)
    for impact, twin in zip(plan.impacts, twins):
        pairs = list(zip(impact.matrices(terms)[:3], twin.matrices(terms)[:3]))
        if impact.friction.count:
            pairs += list(zip(impact.edge_matrices(terms), twin.edge_matrices(terms)))
        for ours, theirs in pairs:
            np.testing.assert_allclose(ours, theirs, rtol=0.0, atol=1e-12 * np.abs(theirs).max())
        assert impact.is_active(terms) == twin.is_active(terms)
    impact, twin = plan.impacts[0], twins[0]
    impact.rule = type(impact.rule)(always_active=not impact.rule.always_active, lookahead_distance=0.0, lookahead_time=0.0)
    twin.rule = impact.rule
    terms = robot.terms(terms.q, terms.dq, check_limits=False)  # a new fill of the same state
    plan.fill(terms, cycle)
    assert impact.is_active(terms) == twin.is_active(terms)


def test_a_slip_preview_or_a_closed_form_model_leaves_the_impacts_to_update_themselves(robot):
    """The plan's kernel updates the crb, gm and classical impacts of a fixed base, without
    friction rows or with a pyramid's; not a one-step preview's (its edges follow the slip) nor
    the classical_normal model's."""
    surface = surface_ahead(robot, start(robot), 0.05)
    for name in ("crb", "gm", "classical"):
        assert ExpectedImpact(surface, name, friction=FrictionRows(0.3, mode="pyramid")).plan_updates_it
    assert not ExpectedImpact(surface, "crb", friction=FrictionRows(0.3, mode="slip")).plan_updates_it
    assert not ExpectedImpact(surface, "classical_normal").plan_updates_it
