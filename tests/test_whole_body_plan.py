"""The whole-body cycle plan (``controller.qp.whole_body_plan``): on random standing states of
the G1 its one compiled call writes the QP of the generic assembly (object by object) and of its
numpy twin; the closed loop's commands are the same with and without it; the controllers it
serves and those it leaves to the arm's plan or to the generic assembly."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.qp import ImpactAwareController
from impactqp.controller.qp.cycle_plan import CyclePlan
from impactqp.controller.qp.whole_body_plan import WholeBodyPlan
from impactqp.tasks import SurfaceOffsetTask
from reference.qp import reference_planned_qp
from test_cycle_plan import assert_same_qp, generic_qp, planned_qp, setting_controller
from whole_body_states import approach_velocity, controller, robot, stance, standing_states


def random_cycle(c, name, q, v, rng):
    """The terms of (q, v), the tasks' targets moved off the state, and the cycle after a random
    previous acceleration."""
    terms = robot().terms(q, v)
    c.reset(stance(name), np.zeros(robot().nv))
    c.tasks[1].hold(terms.com + rng.uniform(-0.02, 0.02, 3), 80.0, (1.0, 2.0, 3.0))  # the CoM task
    torso = c.tasks[2]
    torso.target_position = terms.frame("torso").position + rng.uniform(-0.05, 0.05, 3)
    cycle = c._cycle
    cycle.advance(rng.uniform(-1.0, 1.0, robot().nv) * c.ddq_max, c.ddq_max, c._jerk_step)
    return terms, cycle


@settings(max_examples=20, deadline=None)
@given(state=standing_states(), seed=st.integers(0, 2**32 - 1), always=st.booleans(), method=st.sampled_from(["crb", "gm"]))
def test_the_plan_writes_the_generic_qp_and_its_numpy_twin(state, seed, always, method):
    name, q, v = state
    c = controller(name, gap=0.05, method=method, always_active=always)
    assert isinstance(c._plan, WholeBodyPlan)
    terms, cycle = random_cycle(c, name, q, v, np.random.default_rng(seed))
    planned = planned_qp(c, terms, cycle)
    assert_same_qp(planned, generic_qp(c, terms, cycle), 1e-12)
    assert_same_qp(planned, reference_planned_qp(c.tasks, c.layout, terms, cycle), 1e-9)


def test_an_assigned_parameter_reaches_the_plan():
    """A CoM target set after the plan was packed is in the next cycle's QP."""
    c = controller("parallel", always_active=True)
    terms, cycle = random_cycle(c, "parallel", stance("parallel"), np.zeros(robot().nv), np.random.default_rng(5))
    before = planned_qp(c, terms, cycle)
    c.tasks[1].hold(terms.com + np.array([0.05, 0.0, 0.0]), 80.0, (1.0, 2.0, 3.0))
    after = planned_qp(c, terms, cycle)
    assert not np.allclose(before[1], after[1])
    assert_same_qp(after, generic_qp(c, terms, cycle), 1e-12)


def test_commands_with_and_without_the_plan_are_equal():
    """The closed approach loop's commands, from the plan and from the generic assembly, fed
    the same states, through the impact rows' activation."""
    planned, generic = (controller("parallel", gap=0.05, speed=0.5) for _ in range(2))
    generic._plan = None
    q = stance("parallel")
    v = approach_velocity(q, 0.2)
    active = []
    for c in (planned, generic):
        c.reset(q, v)
    for _ in range(300):
        command, reference = planned.step(q, v), generic.step(q, v)
        assert command.status == reference.status
        for field in ("ddq", "dq_cmd", "q_cmd", "predicted_jump"):
            assert np.allclose(getattr(command, field), getattr(reference, field), rtol=0.0, atol=1e-10)
        active.append(command.impact_constraints_active)
        q, v = command.q_cmd, command.dq_cmd
    assert any(active)


def test_the_plans_a_controller_gets():
    """The G1's default set: the whole-body plan; with a task that has no kernel: the generic
    assembly; an arm's set: the arm's plan."""
    c = controller("parallel")
    assert isinstance(c._plan, WholeBodyPlan)
    offset = SurfaceOffsetTask([-1.0, 0.0, 0.0], [0.5, 0.0, 0.5], 0.02)
    assert ImpactAwareController(robot(), [*c.tasks, offset], c.constraints, c.dt)._plan is None
    assert type(setting_controller(RobotModel("panda"), "crb")._plan) is CyclePlan
