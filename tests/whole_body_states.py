"""The standing G1, its random states and its default controller, shared by the whole-body QP
tests."""

from functools import lru_cache

import numpy as np
import pinocchio as pin
from hypothesis import strategies as st
from reference.whole_body import feet_held_pinv

from impactqp.controller.model.capture import GRAVITY
from impactqp.controller.model.humanoid_stance import STANCES, convex_hull, inside_polygon, stance_posture
from impactqp.controller.model.max_speed import standing_wrenches
from impactqp.controller.model.postures import Surface
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.config import ControllerConfig, build_controller

NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall in front (+x), normal towards the robot


@lru_cache(maxsize=1)
def robot() -> RobotModel:
    return RobotModel("g1")


@lru_cache(maxsize=None)
def stance(name: str) -> np.ndarray:
    return stance_posture(robot(), STANCES[name])


def upright(height: float = 0.7) -> np.ndarray:
    """The G1's neutral configuration (joints at zero, base upright) with its base ``height`` m up."""
    q = pin.neutral(robot().model)
    q[2] = height
    return q


def wall_ahead(q: np.ndarray, gap: float = 0.05) -> Surface:
    """The wall ``gap`` m in front of the hand's contact point."""
    return Surface(robot().terms(q).contact_point - gap * NORMAL, NORMAL)


def standing_states(max_joint_offset: float = 0.05, max_speed: float = 0.3):
    """(stance name, q, v): a stance's posture with its joints moved by up to
    ``max_joint_offset`` rad (inside their limits) and a velocity that keeps both feet still
    (v = N w, N the projector onto the null space of the feet's Jacobian, joint rates up to
    ``max_speed`` rad/s before the projection)."""
    n = robot().n_joints
    offsets = st.lists(st.floats(-1.0, 1.0), min_size=n, max_size=n).map(np.array)
    rates = st.lists(st.floats(-1.0, 1.0), min_size=n, max_size=n).map(np.array)

    def build(name, offset, rate):
        model = robot()
        q = stance(name).copy()
        joints = slice(model.base_nq, None)
        q[joints] = np.clip(q[joints] + max_joint_offset * offset, model.q_min + 1e-3, model.q_max - 1e-3)
        Jf = model.terms(q).held_jacobian
        w = np.concatenate([np.zeros(model.base_nv), max_speed * rate])
        v = w - Jf.T @ np.linalg.solve(Jf @ Jf.T, Jf @ w)
        return name, q, v

    return st.builds(build, st.sampled_from(sorted(STANCES)), offsets, rates)


def approach_velocity(q: np.ndarray, speed: float) -> np.ndarray:
    """The least-norm velocity with both feet still and the hand at ``speed`` towards the wall."""
    terms = robot().terms(q)
    return feet_held_pinv(terms.J, terms.held_jacobian) @ (-speed * NORMAL)


def integrate(q: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
    return pin.integrate(robot().model, q, v * dt)


def controller(name: str, gap: float = 0.05, speed: float = 0.3, method: str = "crb", **options):
    """The G1's default controller (``ControllerConfig.approach``) at stance ``name``, the wall
    ``gap`` m ahead; ``options`` are ``ApproachOptions`` fields."""
    q = stance(name)
    config = ControllerConfig.approach(wall_ahead(q, gap), speed, robot="g1", jump_model=method, **options)
    return build_controller(config, robot(), q)


def vertex_impulses(W: np.ndarray, v_minus: np.ndarray, directions: np.ndarray, restitution: float = 0.0) -> np.ndarray:
    """Each edge d's impulse that ends compression, n^T (v- + W p d) = 0, times 1 + c_r (the
    denominator n^T W d guarded at 0.1 n^T W n, the friction rows' EDGE_GUARD): rows of 3."""
    n = NORMAL
    denominators = np.maximum(directions @ (W.T @ n), 0.1 * (n @ W @ n))
    return -(1.0 + restitution) * (n @ v_minus) / denominators[:, None] * directions


def criterion_margins(q: np.ndarray, dq_pre: np.ndarray, jump, heights: np.ndarray, duration: float) -> dict:
    """Each closed-form criterion's smallest margin (>= 0: met, 0: tight) for the pre-impact
    velocity ``dq_pre`` and a predicted impact ``jump`` (``JumpPrediction``: its jump, hand impulse
    and the feet's impulsive wrenches), from first principles: the joint velocities before and
    after; the feet's wrenches F_k = T w_k + lambda_k (T = ``duration``) in the foot's axes against
    the cone and the sole (the centre of pressure on the sole's plane); and the capture point
    c + dc+ / omega (dc+ = (iota + the feet's impulsive forces) / m) against the soles' corners
    projected from the CoM onto the floor (corner heights ``heights``)."""
    g1 = robot()
    terms = g1.terms(q)
    joints = slice(g1.base_nv, None)
    worst = np.maximum(np.abs(dq_pre[joints]), np.abs((dq_pre + jump.dq_jump)[joints])) / g1.dq_max
    margins = {"joint_velocity": 1.0 - worst.max()}
    wrenches = duration * standing_wrenches(g1, terms) + jump.held_impulse
    placements = g1.frame_placements(q)
    slip, lift = np.inf, np.inf
    for k, contact in enumerate(g1.description.held_contacts):
        R = placements[contact.frame].rotation
        f, tau = R.T @ wrenches[6 * k:6 * k + 3], R.T @ wrenches[6 * k + 3:6 * k + 6]
        slip = min(slip, (contact.friction * f[2] - np.linalg.norm(f[:2])) / f[2])
        cop = np.array([-contact.depth * f[0] - tau[1], tau[0] - contact.depth * f[1]]) / f[2]
        lift = min(lift, inside_polygon(cop, convex_hull(contact.sole)))
    margins.update(foot_slip=slip, foot_lift=lift)
    com = terms.com
    corners = g1.sole_corners(q)[:, :2]
    projected = com[:2] + (com[2] / (com[2] - heights))[:, None] * (corners - com[:2])
    # the CoM velocity jump from the momentum balance: the hand's and the feet's impulsive forces
    com_jump = (jump.impulse + jump.held_impulse[0:3] + jump.held_impulse[6:9]) / terms.mass
    capture_point = com[:2] + com_jump[:2] / np.sqrt(GRAVITY / com[2])
    margins["capture"] = inside_polygon(capture_point, convex_hull(projected))
    return margins
