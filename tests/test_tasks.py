"""Tasks: each residual encodes its control law (identities, not copied numbers)."""

import numpy as np
import pinocchio as pin
import pytest
from conftest import JOINTS, joint_positions, unit_vectors
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from reference.tasks import reference_rows

from impactqp.controller.model.robot_description import PANDA
from impactqp.tasks import CentreOfMassTask, ContactApproachTask, DampingTask, FrameTask, PostureTask, SurfaceOffsetTask
from impactqp.controller.model.robot import SingularPostureError
from impactqp.tasks.task import OrientationHold, Task, rotation_error, rotation_log


@pytest.fixture(scope="module")
def terms(robot):
    q = PANDA.postures["elbow_up"].q
    dq = np.linspace(-0.3, 0.3, JOINTS)
    return robot.terms(q, dq)


def frame_acceleration(terms, ddq):
    return terms.J6 @ ddq + terms.dJ6_dq


def exact_solution(rows):
    return np.linalg.lstsq(rows.A, rows.b, rcond=None)[0]


def test_rotation_error_is_the_rotation_vector_from_current_to_target():
    w = np.array([0.1, -0.2, 0.3])
    R = pin.exp3(np.array([0.4, 0.1, -0.5]))
    assert np.allclose(rotation_error(pin.exp3(w) @ R, R), w)


def test_frame_task_rows_give_the_pd_frame_acceleration(terms):
    target_p = terms.contact_point + np.array([0.01, -0.02, 0.03])
    target_R = pin.exp3(np.array([0.05, 0.0, -0.02])) @ terms.contact_rotation
    task = FrameTask(target_p, target_R, stiffness=50.0, position_weight=2.0, orientation_weight=3.0)
    rows = task.compute(terms)
    twist = terms.J6 @ terms.dq
    expected = np.concatenate([50.0 * (target_p - terms.contact_point), 50.0 * np.array([0.05, 0.0, -0.02])])
    expected -= task.damping * twist
    assert task.damping == pytest.approx(2.0 * np.sqrt(50.0))
    assert np.allclose(frame_acceleration(terms, exact_solution(rows)), expected, atol=1e-9)
    assert np.allclose(rows.weight, [2, 2, 2, 3, 3, 3])


def test_frame_task_holds_the_pose_captured_at_reset(robot):
    terms = robot.terms(PANDA.postures["elbow_left"].q)
    task = FrameTask()
    task.reset(terms)
    assert np.allclose(task.compute(terms).b, -terms.dJ6_dq)


def test_contact_approach_rows_track_the_reference_velocity_in_the_surface_frame(terms):
    normal = np.array([-1.0, 0.0, 0.0])
    task = ContactApproachTask(normal, speed=0.3, tangential_velocity=[0.0, 0.05, 0.0], velocity_gain=10.0)
    task.reset(terms)
    assert np.allclose(task.basis @ task.basis.T, np.eye(3))
    assert np.allclose(task.basis[0], normal)
    rows = task.compute(terms)
    accel = frame_acceleration(terms, exact_solution(rows))
    v = terms.J @ terms.dq
    assert np.allclose(accel[:3], 10.0 * (np.array([0.3, 0.05, 0.0]) - v), atol=1e-9)
    assert np.allclose(accel[3:], -task.orientation_damping * (terms.J6[3:] @ terms.dq), atol=1e-9)
    assert rows.weight[1] == rows.weight[2] and rows.weight[0] != rows.weight[1]


def test_contact_approach_rejects_a_tangential_velocity_along_the_normal():
    with pytest.raises(ValueError):
        ContactApproachTask([0.0, 0.0, 1.0], 0.1, tangential_velocity=[0.0, 0.1, 0.1])
    with pytest.raises(ValueError):
        ContactApproachTask([0.0, 0.0, 1.0], -0.1)


def test_posture_task_is_a_joint_pd(terms):
    target = terms.q + 0.1
    task = PostureTask(target, stiffness=4.0, weight=0.5)
    rows = task.compute(terms)
    assert np.allclose(rows.A, np.eye(len(terms.dq)))
    assert np.allclose(rows.b, 4.0 * 0.1 - 4.0 * terms.dq)
    captured = PostureTask(joints=len(terms.dq))
    captured.reset(terms)
    assert np.allclose(captured.compute(terms).b, -captured.damping * terms.dq)
    with pytest.raises(ValueError, match="target or its number of joints"):
        PostureTask()


def test_damping_task_opposes_the_velocity(terms):
    rows = DampingTask(len(terms.dq), gain=3.0, weight=1e-3).compute(terms)
    assert np.allclose(rows.b, -3.0 * terms.dq)
    assert np.allclose(rows.weight, 1e-3)
    with pytest.raises(ValueError):
        DampingTask(len(terms.dq), weight=0.0)


@pytest.mark.parametrize("offset", [0.05, 0.0, -0.001])
def test_surface_offset_target_is_at_the_offset_along_the_normal_through_the_reset_point(terms, offset):
    surface = PANDA.postures["elbow_up"].surface
    task = SurfaceOffsetTask(surface.normal, surface.point, offset)
    task.reset(terms)
    assert surface.signed_distance(task.target_position) == pytest.approx(offset, abs=1e-12)
    # the target differs from the reset point only along the normal
    shift = task.target_position - terms.contact_point
    assert np.allclose(shift - (shift @ surface.normal) * surface.normal, 0.0, atol=1e-12)
    assert np.allclose(task.target_rotation, terms.contact_rotation)


def test_surface_offset_rows_give_the_saturated_velocity_law(terms):
    surface = PANDA.postures["elbow_up"].surface
    task = SurfaceOffsetTask(surface.normal, surface.point, 0.05, max_speed=0.1, position_gain=20.0, velocity_gain=40.0)
    task.reset(terms)
    task.target_position = terms.contact_point + np.array([-0.2, 0.0, 0.0])  # far: the speed saturates
    accel = frame_acceleration(terms, exact_solution(task.compute(terms)))
    v = terms.J @ terms.dq
    assert np.allclose(accel[:3], 40.0 * (np.array([-0.1, 0.0, 0.0]) - v), atol=1e-9)
    assert np.allclose(accel[3:], -task.orientation_damping * (terms.J6[3:] @ terms.dq), atol=1e-9)
    task.target_position = terms.contact_point + np.array([-0.001, 0.0, 0.0])  # near: proportional
    accel = frame_acceleration(terms, exact_solution(task.compute(terms)))
    assert np.allclose(accel[:3], 40.0 * (20.0 * np.array([-0.001, 0.0, 0.0]) - v), atol=1e-9)


ROTATIONS = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array).filter(lambda v: np.linalg.norm(v) > 1e-3)


@settings(max_examples=200, deadline=None)
@given(axis=ROTATIONS, angle=st.one_of(st.floats(0.0, np.pi), st.floats(np.pi - 1e-3, np.pi), st.floats(0.0, 1e-5)),
       base=ROTATIONS)
def test_compiled_rotation_log_is_pinocchio_log3(axis, angle, base):
    """The kernel's log(R* R^T) equals pinocchio's log3 over all angles, near 0 and near pi
    included (at exactly pi both signs of the axis are the same rotation)."""
    R = pin.exp3(base)
    target = pin.exp3(angle * axis / np.linalg.norm(axis)) @ R
    out = np.empty(3)
    rotation_log(target, R, out)
    expected = pin.log3(target @ R.T)
    if np.pi - np.linalg.norm(expected) < 1e-6:
        assert np.allclose(out, expected, atol=1e-6) or np.allclose(out, -expected, atol=1e-6)
    else:
        np.testing.assert_allclose(out, expected, atol=1e-9)


def test_setting_the_reference_velocity_moves_the_rows_by_its_feed_forward(terms):
    """v* is a public attribute: changing it changes the linear rows by k_v (v*' - v*) in the
    surface frame, and nothing else."""
    normal = np.array([-1.0, 0.0, 0.0])
    task = ContactApproachTask(normal, speed=0.1, velocity_gain=10.0)
    task.reset(terms)
    before = task.compute(terms).b
    old, new = task.reference_velocity.copy(), np.array([0.05, 0.2, -0.1])
    task.reference_velocity = new
    after = task.compute(terms).b
    np.testing.assert_allclose(after[:3] - before[:3], 10.0 * task.basis @ (new - old), atol=1e-12)
    np.testing.assert_array_equal(after[3:], before[3:])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_compiled_task_rows_equal_the_numpy_reference(robot, seed):
    """Every task's compute_into (compiled where the class has a kernel) writes the rows of its
    plain-numpy statement (tests/reference/tasks.py)."""
    rng = np.random.default_rng(seed)
    q = PANDA.postures["elbow_up"].q + rng.uniform(-0.3, 0.3, JOINTS)
    terms = robot.terms(q, rng.uniform(-1.0, 1.0, JOINTS), check_limits=False)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    tasks = [
        ContactApproachTask(normal, 0.2, velocity_gain=15.0, orientation=OrientationHold(stiffness=80.0)),
        PostureTask(target=q + rng.uniform(-0.2, 0.2, JOINTS), stiffness=12.0),
        DampingTask(robot.nv, gain=2.0),
        FrameTask(terms.contact_point + 0.01, pin.exp3(rng.uniform(-1, 1, 3))),
        SurfaceOffsetTask(normal, terms.contact_point, 0.05),
    ]
    for task in tasks:
        task.reset(robot.terms(q + rng.uniform(-0.2, 0.2, JOINTS), check_limits=False))
        A, b = np.full((task.rows, JOINTS), np.nan), np.full(task.rows, np.nan)
        A_ref, b_ref = np.full((task.rows, JOINTS), np.nan), np.full(task.rows, np.nan)
        task.compute_into(terms, A, b)
        reference_rows(task, terms, A_ref, b_ref)
        np.testing.assert_allclose(A, A_ref, rtol=1e-12, atol=1e-12, err_msg=task.name)
        np.testing.assert_allclose(b, b_ref, rtol=1e-10, atol=1e-9, err_msg=task.name)


# ---------------------------------------------------------------- Jacobians by finite differences
# Every task's rows are A ddq = b with A the Jacobian of the quantity the task controls, as in
# mink's tests/test_jacobians.py: A(q) dq must equal the rate of that quantity along dq, taken by
# central finite differences of Pinocchio's forward kinematics (never of the Jacobian itself).
# ``controlled_rate`` names the quantity of each task class; the table must cover them all.
FD_STEP = 1e-6


def frame_rate(robot, q, dq):
    """[dp/dt; w] of the contact frame along dq (world axes): p and log3(R+ R-^T) / 2h."""
    after, before = robot.contact_frame(q + FD_STEP * dq), robot.contact_frame(q - FD_STEP * dq)
    linear = (after.translation - before.translation) / (2 * FD_STEP)
    angular = pin.log3(after.rotation @ before.rotation.T) / (2 * FD_STEP)
    return np.concatenate([linear, angular])


def approach_rate(robot, task, q, dq):
    rate = frame_rate(robot, q, dq)
    return np.concatenate([task.basis @ rate[:3], rate[3:]])


CONTROLLED_RATE = {
    FrameTask: lambda robot, task, q, dq: frame_rate(robot, q, dq),
    SurfaceOffsetTask: lambda robot, task, q, dq: frame_rate(robot, q, dq),
    ContactApproachTask: approach_rate,
    PostureTask: lambda robot, task, q, dq: dq,  # joint positions
    DampingTask: lambda robot, task, q, dq: dq,
}


def all_task_classes(kind=Task):
    return {sub for direct in kind.__subclasses__() for sub in {direct} | all_task_classes(direct)}


def test_the_jacobian_table_covers_every_task():
    """Every task of the arm is in the table; the CoM task exists only on the floating base
    (test_com_task.py checks its Jacobian against finite differences)."""
    assert all_task_classes() == set(CONTROLLED_RATE) | {CentreOfMassTask}


def one_task_of_each_class(normal, terms):
    return [
        FrameTask(),
        SurfaceOffsetTask(normal, terms.contact_point - 0.01 * normal, 0.02),
        ContactApproachTask(normal, 0.1, tangential_velocity=0.05 * np.cross(normal, [0.0, 0.0, 1.0])),
        PostureTask(joints=len(terms.dq)),
        DampingTask(len(terms.dq)),
    ]


@settings(max_examples=40, deadline=None)
@given(q=joint_positions(0.05), direction=st.lists(st.floats(-1.0, 1.0), min_size=JOINTS, max_size=JOINTS), normal=unit_vectors())
def test_every_task_jacobian_matches_finite_differences_of_what_it_controls(robot, q, direction, normal):
    dq = np.asarray(direction)
    try:
        terms = robot.terms(q, dq)
    except SingularPostureError:
        reject()
    for task in one_task_of_each_class(normal, terms):
        task.reset(terms)
        A = task.compute(terms).A
        expected = CONTROLLED_RATE[type(task)](robot, task, q, dq)
        np.testing.assert_allclose(A @ dq, expected, atol=1e-6, err_msg=task.name)


def test_joint_tasks_on_a_floating_base_act_on_the_trailing_joints_only():
    """PostureTask(joints=joints) and DampingTask(variables=nv) on the standing G1: [0 I] dv = b
    for the posture (the base's accelerations free), I dv = -gain v for the damping."""
    from whole_body_states import approach_velocity, robot, stance

    model = robot()
    joints, base = model.n_joints, model.base_nv
    q = stance("parallel")
    v = approach_velocity(q, 0.4)
    terms = model.terms(q, v)
    posture = PostureTask(target=q[model.base_nq:] + 0.1, stiffness=9.0, damping=2.0, joints=joints)
    rows = posture.compute(terms)
    np.testing.assert_array_equal(rows.A, np.hstack([np.zeros((joints, base)), np.eye(joints)]))
    np.testing.assert_allclose(rows.b, 9.0 * 0.1 - 2.0 * v[base:])
    posture = PostureTask(joints=joints)
    posture.reset(terms)
    np.testing.assert_array_equal(posture.target, q[model.base_nq:])
    damping = DampingTask(variables=model.nv, gain=3.0).compute(terms)
    np.testing.assert_array_equal(damping.A, np.eye(model.nv))
    np.testing.assert_allclose(damping.b, -3.0 * v)


def test_frame_task_on_a_named_frame_drives_that_frame():
    """FrameTask(frame="torso") reads the torso's pose, Jacobian and drift from the terms."""
    from whole_body_states import approach_velocity, robot, stance

    q = stance("wide")
    terms = robot().terms(q, approach_velocity(q, 0.3))
    torso = terms.frame("torso")
    task = FrameTask(stiffness=16.0, frame="torso")
    task.reset(terms)
    np.testing.assert_array_equal(task.target_position, torso.position)
    rows = task.compute(terms)
    assert task.name == "frame[torso]"
    np.testing.assert_array_equal(rows.A, torso.J6)
    np.testing.assert_allclose(rows.b, -8.0 * (torso.J6 @ terms.dq) - torso.dJ6_dq)
