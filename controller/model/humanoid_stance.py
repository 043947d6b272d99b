"""Standing postures of the floating-base G1 before a hand impact (docs/floating-base.md).

A stance (``robot_description.Stance``: a description's ``stances``, :data:`STANCES` the G1's)
places the sole of each held contact k flat on its support surface (z = ``stance.height(k)``:
the floor, 0, or a step; the contact's frame ``depth`` above it) with its frame at the horizontal position ``feet[k]``, the centre of mass over the
mean of the soles' centres (each frame's position moved along x by the mean x of its sole's
corners) and the hand's contact point at a target with the forearm pointing forward (+x,
towards the wall). The posture is found by damped
Gauss-Newton over the whole configuration (base placement and joints), every task stacked with
a weight (feet and CoM first, then the hand, then a small pull towards a nominal bent-knee
posture that keeps the solution unique):

    dv = argmin sum_k w_k^2 |A_k dv - e_k|^2 + lambda^2 |dv|^2,    q <- integrate(q, dv)

with e_k = log6(T_k^-1 T_k*) and A_k = J_k (frame Jacobian in the frame) for the feet and the
hand's orientation, e = c*_xy - c_xy with A = Jcom_xy for the CoM, e = p* - p with the
world-aligned Jacobian for the hand's position. Joints are clipped into their limits.
This is a floating-base, multi-frame problem; the arm's ``inverse_kinematics`` solves one frame of
a fixed base.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .robot import RobotModel
from .robot_description import ROBOTS, Stance
from .held_contact_description import convex_hull
from .validation import BadInputError

WEIGHTS = {"feet": 10.0, "com": 10.0, "hand": 3.0, "hand_axis": 1.0, "posture": 0.05}
DAMPING = 1e-3
ITERATIONS = 200
STANCES = ROBOTS["g1"].stances
"""The G1's stances by name (its description's): parallel, wide, staggered, close, far (flat) and step (the left foot on a step)."""


def support_polygon(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Convex hull (counter-clockwise, k x 2) of both soles' corners, from the posture q."""
    points = robot.sole_corners(q)[:, :2]
    return convex_hull(points)


def edge_normals(polygon: np.ndarray) -> np.ndarray:
    """(k, 2): the unit outward normal of each edge (vertex i to i + 1) of the counter-clockwise
    convex ``polygon`` (k x 2)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    return np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]


def edge_margins(polygon: np.ndarray, point) -> np.ndarray:
    """(k): the distance of ``point`` (x, y) inside each edge of the counter-clockwise convex
    ``polygon`` (positive inside, negative outside)."""
    return np.einsum("ij,ij->i", edge_normals(polygon), polygon - np.asarray(point, dtype=float)[:2])


def inside_polygon(point, polygon: np.ndarray) -> float:
    """Signed distance-like margin: the smallest distance of ``point`` to the edges of the
    counter-clockwise convex ``polygon`` (positive inside, negative outside)."""
    return float(edge_margins(polygon, point).min())


def stance_posture(robot: RobotModel, stance: Stance) -> np.ndarray:
    """The configuration q (nq) of the stance (module docstring); raises BadInputError when the
    solver leaves a foot more than 1 mm (or 1 mrad) off its target or the hand 5 mm off."""
    model = robot.model
    joints = slice(robot.base_nq, None)  # the actuated joints' part of q
    nominal = np.zeros(robot.n_joints)
    for name, value in robot.description.nominal_posture.items():
        nominal[robot.joint_index(name)] = value
    contacts = robot.description.held_contacts
    if len(stance.feet) != len(contacts):
        raise BadInputError(f"stance {stance.name!r} places {len(stance.feet)} feet, the robot holds {len(contacts)} contacts")
    feet = [(fid, pin.SE3(np.eye(3), np.array([*xy, stance.height(k) + c.depth])))
            for k, (fid, c, xy) in enumerate(zip(robot.held_frame_ids, contacts, stance.feet))]
    centre = np.mean([[xy[0] + float(c.sole[:, 0].mean()), xy[1]] for c, xy in zip(contacts, stance.feet)], axis=0)
    hand_target = np.array(stance.hand)
    q = pin.neutral(model)
    q[2] = 0.75
    q[joints] = nominal
    for _ in range(ITERATIONS):
        rows, errors = _tasks(robot, q, feet, centre, hand_target, nominal)
        A, e = np.vstack(rows), np.concatenate(errors)
        dv = np.linalg.solve(A.T @ A + DAMPING**2 * np.eye(model.nv), A.T @ e)
        q = pin.integrate(model, q, dv)
        q[joints] = np.clip(q[joints], robot.q_min, robot.q_max)
    _, errors = _tasks(robot, q, feet, centre, hand_target, nominal)
    foot_error = max(np.abs(e).max() for e in errors[:len(feet)]) / WEIGHTS["feet"]
    hand_error = np.linalg.norm(errors[len(feet) + 1]) / WEIGHTS["hand"]
    if foot_error > 1e-3 or hand_error > 5e-3:
        raise BadInputError(
            f"stance {stance.name!r} cannot be reached: foot error {foot_error:.2e}, hand error {hand_error:.2e} m"
        )
    return q


def _tasks(robot, q, feet, centre, hand_target, nominal):
    """Weighted task rows and errors of the stance solver (module docstring)."""
    model, data = robot.model, robot.data
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    w = WEIGHTS
    rows, errors = [], []
    for fid, target in feet:
        rows.append(w["feet"] * pin.getFrameJacobian(model, data, fid, pin.LOCAL))
        errors.append(w["feet"] * pin.log6(data.oMf[fid].inverse() * target).vector)
    Jcom = pin.jacobianCenterOfMass(model, data, q)
    rows.append(w["com"] * Jcom[:2])
    errors.append(w["com"] * (centre - data.com[0][:2]))
    hand = robot.contact_frame_id
    J6 = pin.getFrameJacobian(model, data, hand, pin.LOCAL_WORLD_ALIGNED)
    rows.append(w["hand"] * J6[:3])
    errors.append(w["hand"] * (hand_target - data.oMf[hand].translation))
    # forearm (frame x axis) along world +x: the rotation turning x onto +x, as in the arm's IK
    x_axis = data.oMf[hand].rotation[:, 0]
    rows.append(w["hand_axis"] * J6[3:])
    errors.append(w["hand_axis"] * np.cross(x_axis, np.array([1.0, 0.0, 0.0])))
    posture = np.zeros((robot.n_joints, model.nv))
    posture[:, robot.base_nv:] = np.eye(robot.n_joints)
    rows.append(w["posture"] * posture)
    errors.append(w["posture"] * (nominal - q[robot.base_nq:]))
    return rows, errors
