"""States and controllers shared by the tests of the QP package (tests/test_qp_*.py)."""

import numpy as np

from conftest import JOINTS
from impactqp.controller.config import ControllerConfig, build_controller
from impactqp.controller.model.jump import jump_model
from impactqp.controller.model.max_speed import approach_direction
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import SingularPostureError

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
    return build_controller(config, robot)


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
        q = robot.q_min + span * rng.uniform(0.15, 0.85, JOINTS)
        try:
            terms = robot.terms(q)
        except SingularPostureError:
            continue
        dq = rng.uniform(0.0, 0.3) * approach_direction(robot, terms, NORMAL) + rng.uniform(-0.05, 0.05, JOINTS)
        for _ in range(20):
            if state_satisfies_the_limits(robot, robot.terms(q, dq), models, restitution):
                return q, dq
            dq = 0.5 * dq
