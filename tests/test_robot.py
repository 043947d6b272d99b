"""The robot model: fingers locked, real inertials, contact tool, limits, postures; every robot
with every tool."""

import re
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from cli_checks import one_line_bad_input, run
from conftest import ARMS, joint_positions
from hypothesis import given, settings
from hypothesis import strategies as st
from test_jump import welded_arm_inverse_inertia
from whole_body_states import integrate, standing_states, upright
from whole_body_states import robot as g1_robot

from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import (
    CONTACT_FRAME,
    HAND_FRAME,
    TOOL_TIP_OFFSET,
    InvalidStateError,
    RobotModel,
    SingularPostureError,
)
from impactqp.controller.model.jump import crb_inverse_inertia
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.tool_description import TOOLS

# A posture inside the limits where the contact Jacobian loses rank (found by minimising its
# smallest singular value).
SINGULAR_Q = np.array([-0.63343, 3e-05, 1.5708, -0.467, 0.0, 3.01097, 2.8973])


def test_model_is_the_described_arm_with_real_masses(robot):
    assert robot.model.nq == robot.nq == robot.nv == len(robot.description.joints)
    masses = [robot.model.inertias[i].mass for i in range(1, robot.model.njoints)]
    assert all(m > 0 for m in masses)
    terms = robot.terms(PANDA.postures["elbow_up"].q)
    assert terms.mass == pytest.approx(sum(masses))


def test_limits_are_the_datasheet_ones(robot):
    np.testing.assert_allclose(robot.dq_max, [2.175] * 4 + [2.61] * 3)
    np.testing.assert_allclose(robot.tau_max, [87] * 4 + [12] * 3)
    np.testing.assert_allclose(robot.ddq_max, [15, 7.5, 10, 12.5, 15, 20, 20])
    np.testing.assert_allclose(robot.dddq_max, [7500, 3750, 5000, 6250, 7500, 10000, 10000])
    assert np.all(robot.q_min < robot.q_max)


@settings(max_examples=20, deadline=None)
@given(q=joint_positions())
def test_contact_frame_is_on_the_hand_axis(robot, q):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    hand = data.oMf[robot.model.getFrameId(HAND_FRAME)]
    tip = data.oMf[robot.model.getFrameId(CONTACT_FRAME)]
    np.testing.assert_allclose(tip.translation, hand.translation + TOOL_TIP_OFFSET * hand.rotation[:, 2], atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(q=joint_positions(), dq=joint_positions(0.0))
def test_terms_match_pinocchio_and_finite_differences(robot, q, dq):
    dq = 0.3 * (dq - robot.q_min) / (robot.q_max - robot.q_min) - 0.15
    terms = robot.terms(q, dq)
    data = robot.model.createData()
    np.testing.assert_allclose(terms.M, pin.crba(robot.model, data, q), atol=1e-10)
    np.testing.assert_allclose(terms.M, terms.M.T)
    np.testing.assert_allclose(terms.h, pin.rnea(robot.model, data, q, dq, np.zeros(robot.nv)), atol=1e-9)
    # contact velocity is J dq, and its derivative along the motion is dJ dq (ddq = 0)
    eps = 1e-6
    p_plus, p_minus = robot.contact_point(q + eps * dq), robot.contact_point(q - eps * dq)
    np.testing.assert_allclose((p_plus - p_minus) / (2 * eps), terms.J @ dq, atol=1e-7)
    J_plus = robot.contact_jacobian6(q + eps * dq)
    J_minus = robot.contact_jacobian6(q - eps * dq)
    np.testing.assert_allclose((J_plus - J_minus) @ dq / (2 * eps), terms.dJ6_dq, atol=1e-6)
    np.testing.assert_allclose(terms.J @ terms.J_pinv, np.eye(3), atol=1e-9)


def test_bad_states_are_rejected(robot):
    q = PANDA.postures["elbow_up"].q
    with pytest.raises(InvalidStateError, match=f"{robot.nq} values"):
        robot.terms(q[:-1])
    with pytest.raises(InvalidStateError, match="non-finite"):
        robot.terms(np.where(np.arange(robot.nq) == 2, np.nan, q))
    with pytest.raises(InvalidStateError, match="non-finite"):
        robot.terms(q, np.full(robot.nv, np.inf))
    with pytest.raises(InvalidStateError, match="outside the joint limits"):
        robot.terms(q + np.where(np.arange(robot.nq) == 3, 5.0, 0.0))
    with pytest.raises(SingularPostureError, match="singular"):
        robot.terms(SINGULAR_Q)
    assert np.linalg.svd(robot.contact_jacobian6(SINGULAR_Q)[:3], compute_uv=False)[-1] < 1e-6


@pytest.mark.parametrize("robot_name, name", [(r, p) for r in ARMS for p in ROBOTS[r].postures])
def test_named_postures_face_the_default_wall(robot_name, name):
    robot = RobotModel(robot_name)
    p = robot.description.posture(name)
    assert p.surface is DEFAULT_WALL
    assert np.all(p.q - robot.q_min >= 0.1) and np.all(robot.q_max - p.q >= 0.1)
    terms = robot.terms(p.q)
    assert abs(p.surface.signed_distance(terms.contact_point)) < 1e-5
    np.testing.assert_allclose(terms.contact_rotation[:, 2], -p.surface.normal, atol=1e-5)
    sv = np.linalg.svd(terms.J6, compute_uv=False)
    assert sv[-1] / sv[0] > 0.02  # non-singular, also for the 6-D frame Jacobian


def test_postures_differ_in_elbow_and_wrist(robot):
    qs = np.array([p.q for p in PANDA.postures.values()])
    assert len(qs) >= 3
    def side(angle):
        return 0 if abs(angle) < 0.3 else int(np.sign(angle))

    assert {side(q[2]) for q in qs} == {-1, 0, 1}  # elbow swung right, left, centred
    assert {side(q[4]) for q in qs} == {-1, 0, 1}  # wrist rolled down, up, neutral


def test_unknown_posture_and_bad_surface():
    for description in ROBOTS.values():
        with pytest.raises(BadInputError, match=f"unknown posture 'nope' for the {description.name}"):
            description.posture("nope")
    with pytest.raises(ValueError, match="zero"):
        Surface(np.zeros(3), np.zeros(3))
    assert np.linalg.norm(Surface(np.zeros(3), np.array([0, 0, 2.0])).normal) == 1.0


# ---------------------------------------------------------------- every robot with every tool
ROBOT_TOOLS = [(robot, tool) for robot in ARMS for tool in TOOLS]


@pytest.fixture(scope="module", params=ROBOT_TOOLS, ids=lambda pair: "-".join(pair))
def model(request):
    return RobotModel(*request.param)


def model_positions(model, u):
    return model.q_min + 0.1 + np.asarray(u)[: model.nq] * (model.q_max - model.q_min - 0.2)


MOST_JOINTS = max(len(ROBOTS[name].joints) for name in ARMS)
unit_cube = st.lists(st.floats(0.0, 1.0), min_size=MOST_JOINTS, max_size=MOST_JOINTS)  # the first nq serve a robot


@settings(max_examples=15, deadline=None)
@given(u=unit_cube)
def test_crb_inverse_inertia_is_the_welded_body_for_every_robot_and_tool(model, u):
    q = model_positions(model, u)
    try:
        terms = model.terms(q)
    except SingularPostureError:
        return
    np.testing.assert_allclose(crb_inverse_inertia(terms), welded_arm_inverse_inertia(model, q), atol=1e-12)


@pytest.fixture(scope="module")
def loaded_and_bare(model):
    """The model's tool (given a mass when it has none) and the same tool without mass."""
    tool = model.tool
    if tool.mass == 0.0:
        tool = replace(tool, mass=1.2, com=tool.contact_point, inertia=np.diag([2e-3, 2e-3, 1e-3]))
    bare = replace(tool, mass=0.0, com=np.zeros(3), inertia=np.zeros((3, 3)))
    return RobotModel(model.description, tool), RobotModel(model.description, bare)


@settings(max_examples=15, deadline=None)
@given(u=unit_cube)
def test_a_tools_mass_is_a_payload_of_its_link(loaded_and_bare, u):
    """The tool adds exactly a rigid body on its frame: to M its J_b^T I J_b (J_b the body
    Jacobian of the frame, I the tool's spatial inertia there), and to the locked inertia of the
    CRB model (20) its inertia moved to the world."""
    loaded_model, bare = loaded_and_bare
    tool = loaded_model.tool
    q = model_positions(bare, u)
    loaded, empty = loaded_model.terms(q, check_limits=False), bare.terms(q, check_limits=False)
    Jb = pin.computeFrameJacobian(bare.model, bare.data, q, bare.tool_frame_id, pin.LOCAL)
    np.testing.assert_allclose(loaded.M, empty.M + Jb.T @ tool.spatial_inertia.matrix() @ Jb, atol=1e-12)
    pin.framesForwardKinematics(bare.model, bare.data, q)
    world_tool = bare.data.oMf[bare.tool_frame_id].act(tool.spatial_inertia)
    expected = pin.Inertia(empty.mass, empty.com, empty.inertia_com) + world_tool
    assert loaded.mass == pytest.approx(empty.mass + tool.mass, abs=1e-12)
    np.testing.assert_allclose(loaded.com, expected.lever, atol=1e-12)
    np.testing.assert_allclose(loaded.inertia_com, expected.inertia, atol=1e-12)


def test_contact_frame_is_the_tools_contact_point(model):
    q = model.description.postures["elbow_up"].q
    mount = model.model.frames[model.tool_frame_id]
    assert mount.name == model.description.frame_of(model.tool)
    pin.framesForwardKinematics(model.model, model.data, q)
    frame = model.data.oMf[model.tool_frame_id]
    np.testing.assert_allclose(model.contact_point(q), frame.act(model.tool.contact_point), atol=1e-12)
    np.testing.assert_allclose(model.contact_frame(q).rotation, frame.rotation, atol=1e-12)


def urdf_inertia(link) -> pin.Inertia:
    """A URDF link's inertial element as a Pinocchio inertia in the link frame."""
    inertial = link.find("inertial")
    origin = inertial.find("origin")
    assert origin.get("rpy", "0 0 0").split() == ["0", "0", "0"]
    i = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
    I = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]])
    com = np.array(list(map(float, origin.get("xyz").split())))
    return pin.Inertia(float(inertial.find("mass").get("value")), com, I)


def test_fr3_links_are_franka_descriptions():
    """franky-sim's fr3.urdf is franka_description's FR3 (its NOTICE): the model's link inertias
    are that file's, read here independently of Pinocchio's parser."""
    model = RobotModel("fr3", "pad")  # the bare arm: the last link carries the pad only
    root = ET.parse(model.description.urdf_path()).getroot()
    links = {link.get("name"): link for link in root.findall("link")}
    last = model.model.njoints - 1
    for i in range(1, last):
        assert model.model.inertias[i].isApprox(urdf_inertia(links[f"fr3_link{i}"]), 1e-12)
    flange = model.model.frames[model.tool_frame_id].placement
    expected_last = urdf_inertia(links[f"fr3_link{last}"]) + flange.act(model.tool.spatial_inertia)
    assert model.model.inertias[last].isApprox(expected_last, 1e-12)


def test_fr3_inverse_inertia_agrees_with_the_menagerie_fr3():
    """A second source: MuJoCo Menagerie's FR3 with the Franka Hand (franky-sim's fr3.xml, its
    inertias rounded and diagonalised independently) gives the Franka Hand's contact-point
    inverse inertia J M^-1 J^T within 5 % of ours (arm block of M: locking the fingers removes
    their rows; rotor armature set to zero, the URDF has none)."""
    import importlib.util

    import mujoco

    xml = Path(importlib.util.find_spec("franky_sim").origin).parent / "assets" / "fr3.xml"
    spec = mujoco.MjSpec.from_file(str(xml))
    spec.meshdir = str(xml.parent / "meshes")
    menagerie = spec.compile()
    menagerie.dof_armature[:] = 0.0
    data = mujoco.MjData(menagerie)
    ours = RobotModel("fr3", "franka_hand")
    hand = mujoco.mj_name2id(menagerie, mujoco.mjtObj.mjOBJ_BODY, "hand")
    for posture in ours.description.postures.values():
        data.qpos[:] = 0.0
        data.qpos[: ours.nq] = posture.q
        mujoco.mj_forward(menagerie, data)
        M = np.zeros((menagerie.nv, menagerie.nv))
        mujoco.mj_fullM(menagerie, data, M)
        point = data.xpos[hand] + data.xmat[hand].reshape(3, 3) @ ours.tool.contact_point
        J = np.zeros((3, menagerie.nv))
        mujoco.mj_jac(menagerie, data, J, None, point, hand)
        arm = slice(ours.nv)
        W = J[:, arm] @ np.linalg.solve(M[arm, arm], J[:, arm].T)
        terms = ours.terms(posture.q)
        np.testing.assert_allclose(terms.contact_point, point, atol=1e-9)
        W_ours = terms.J @ np.linalg.solve(terms.M, terms.J.T)
        assert np.linalg.norm(W - W_ours) <= 0.05 * np.linalg.norm(W_ours)


def test_unknown_robot_or_tool_is_bad_input():
    with pytest.raises(BadInputError, match="unknown robot"):
        RobotModel("kuka")
    with pytest.raises(BadInputError, match="unknown tool"):
        RobotModel("fr3", "hammer")


# ---------------------------------------------------------------------- a floating base (the G1)
G1_SETTINGS = settings(max_examples=10, deadline=None)
EPS = 1e-6


def test_a_floating_base_has_a_free_flyer_before_its_joints():
    g1 = g1_robot()
    assert (g1.base_nq, g1.base_nv) == (7, 6) and g1.floating
    assert g1.n_joints == len(g1.description.joints) == g1.nv - 6 == g1.nq - 7
    assert all(len(limit) == g1.n_joints for limit in (g1.q_min, g1.q_max, g1.dq_max, g1.tau_max, g1.ddq_max, g1.dddq_max))
    arm = RobotModel("panda")
    assert (arm.base_nq, arm.base_nv, arm.n_joints) == (0, 0, arm.nv) and not arm.floating


@G1_SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_g1_terms_match_pinocchio_and_finite_differences(state):
    """M is CRBA's; each held contact's 6 rows are the world-aligned velocity of its frame (the
    translation's rate, then the angular velocity of its rotation: finite differences along v);
    Jcom v is the centre of mass's rate; h is RNEA at zero acceleration."""
    _, q, v = state
    g1 = g1_robot()
    terms = g1.terms(q, v)
    model, data = g1.model, g1.model.createData()
    M = pin.crba(model, data, q)
    np.testing.assert_allclose(terms.M, np.triu(M) + np.triu(M, 1).T, atol=1e-12)
    np.testing.assert_allclose(terms.h, pin.rnea(model, data, q, v, np.zeros(g1.nv)), atol=1e-9)
    after, before = integrate(q, v, EPS), integrate(q, v, -EPS)
    placements = g1.frame_placements(after), g1.frame_placements(before)
    for k, frame in enumerate(g1.held_frames):
        plus, minus = placements[0][frame], placements[1][frame]
        rate = np.concatenate([
            (plus.translation - minus.translation) / (2 * EPS), pin.log3(plus.rotation @ minus.rotation.T) / (2 * EPS)
        ])
        np.testing.assert_allclose(terms.held_jacobian[6 * k:6 * k + 6] @ v, rate, atol=1e-6)
    com_rate = (pin.centerOfMass(model, data, after) - pin.centerOfMass(model, data, before)) / (2 * EPS)
    np.testing.assert_allclose(terms.Jcom @ v, com_rate, atol=1e-7)


@G1_SETTINGS
@given(standing_states(max_joint_offset=0.3, max_speed=1.0))
def test_drifts_are_the_time_derivatives_of_the_jacobians_along_the_motion(state):
    """d/dt (X v) = X dv + dX v: with dv = 0, (X(q + v eps) v - X(q) v) / eps -> dX v for the
    hand, the feet, the torso and the centre of mass (central differences)."""
    _, q, v = state
    model = g1_robot()
    before, after, now = model.terms(integrate(q, v, -EPS), v), model.terms(integrate(q, v, EPS), v), model.terms(q, v)
    pairs = [
        (lambda t: t.J6 @ v, now.dJ6_dq),
        (lambda t: t.held_jacobian @ v, now.held_drift),
        (lambda t: t.Jcom @ v, now.dJcom_dq),
        (lambda t: t.frame("torso").J6 @ v, now.frame("torso").dJ6_dq),
    ]
    for rate, drift in pairs:
        np.testing.assert_allclose((rate(after) - rate(before)) / (2 * EPS), drift, atol=1e-5 * (1 + np.abs(drift).max()))


@G1_SETTINGS
@given(standing_states())
def test_inverse_inertia_and_centre_of_mass_match_their_definitions(state):
    _, q, v = state
    terms = g1_robot().terms(q, v)
    np.testing.assert_allclose(terms.M @ terms.M_inv, np.eye(g1_robot().nv), atol=1e-8)
    np.testing.assert_allclose(terms.M_inv, terms.M_inv.T, atol=1e-12)
    np.testing.assert_allclose(terms.J @ terms.J.T @ terms.JJt_inv, np.eye(3), atol=1e-9)
    # the configuration's terms (v = 0) have the same CoM, its Jacobian and the locked inertia
    still = g1_robot().terms(q)
    np.testing.assert_allclose(terms.Jcom, still.Jcom, atol=1e-12)
    np.testing.assert_allclose(terms.com, still.com, atol=1e-12)
    assert terms.mass == pytest.approx(still.mass)


def test_a_floating_base_checks_sizes_values_and_only_the_joints_limits():
    g1 = g1_robot()
    q, nv = upright(), g1.nv
    for bad_q, bad_v, message in (
        (q[:-1], np.zeros(nv), f"q must have {g1.nq} values"), (q, np.zeros(nv - 1), f"dq must have {nv} values"),
        (q, np.full(nv, np.nan), "non-finite"), (np.where(np.arange(g1.nq) == 9, np.inf, q), np.zeros(nv), "non-finite"),
        (np.where((np.arange(g1.nq) >= 3) & (np.arange(g1.nq) < 7), 0.0, q), np.zeros(nv), "unit quaternion"),
        (np.where(np.arange(g1.nq) == 6, 2.0, q), np.zeros(nv), "unit quaternion"),
    ):
        with pytest.raises(InvalidStateError, match=message):
            g1.terms(bad_q, bad_v)
        with pytest.raises(InvalidStateError, match=message):
            g1.check_state(bad_q, bad_v)
    far = q.copy()
    far[:3] = [50.0, -40.0, 30.0]  # the base's coordinates have no limits
    g1.check_state(far, check_limits=True)
    out = q.copy()
    out[g1.base_nq + 3] = g1.q_max[3] + 0.1
    with pytest.raises(InvalidStateError, match=g1.joint_names[3]) as error:
        g1.check_state(out, check_limits=True)
    assert error.value.constraint == "joint_position_limit" and "\n" not in str(error.value)
    g1.terms(out)  # a floating base's terms do not check the limits unless asked
    with pytest.raises(InvalidStateError):
        g1.terms(out, check_limits=True)


def test_sole_corners_follow_the_feet():
    """At the neutral configuration both soles are flat and at the same height; an arm has none."""
    g1 = g1_robot()
    q = pin.neutral(g1.model)
    corners = g1.sole_corners(q)
    assert corners.shape == (8, 3)
    np.testing.assert_allclose(corners[:, 2], corners[0, 2], atol=1e-9)
    placements = g1.frame_placements(q)
    left, right = g1.held_frames
    assert placements[left].translation[1] > placements[right].translation[1]  # left is +y
    assert RobotModel("panda").sole_corners(PANDA.postures["elbow_up"].q).shape == (0, 3)


def test_held_contacts_on_one_rigid_body_are_bad_input(tmp_path, capsys):
    """A third held contact on the left foot's frame makes the stacked held Jacobian rank 12 of
    18 at every state (Jf M^-1 Jf^T, which the held-contact maps invert, singular): the model
    refuses the description with one line of bad input, in the library and on the command line."""
    g1 = ROBOTS["g1"]
    heel = replace(g1.held_contacts[0], name="left_heel")
    with pytest.raises(BadInputError, match=r"left_foot, right_foot, left_heel\) cannot be held independently: .* rank 12 of 18"):
        RobotModel(replace(g1, held_contacts=(*g1.held_contacts, heel)))
    text = g1.source.read_text()
    text = text.replace("[stances.", '[[held_contacts]]\nname = "left_heel"\nframe = "left_ankle_roll_link"\n'
                        'sole = [[-0.05, 0.025], [-0.05, -0.025], [0.05, 0.0]]\ndepth = 0.035\nfriction = 1.0\n\n[stances.', 1)
    for feet in set(re.findall(r"^feet = (\[\[.*\]\])$", text, flags=re.MULTILINE)):
        text = text.replace(f"feet = {feet}", f"feet = {feet[:-1]}, {feet[1:feet.index(']') + 1]}]")
    text = re.sub(r"^heights = \[(.*?),(.*)\]$", r"heights = [\1,\2, \1]", text, flags=re.MULTILINE)
    path = tmp_path / "g1_heel.toml"
    path.write_text(text)
    code, out, err = run(capsys, "max-speed", "--robot", str(path), "--posture", "parallel")
    one_line_bad_input(code, out, err, "cannot be held independently")


def _my_arm(folder, urdf_edit=None, **changes):
    """The UR5 described as a user's arm in ``folder`` (``test_robot_description._user_arm``),
    its URDF text edited by ``urdf_edit`` = (old, new)."""
    from test_robot_description import _user_arm

    path = _user_arm(folder, **changes)
    if urdf_edit is not None:
        urdf = folder / "my_arm.urdf"
        text = urdf.read_text()
        assert urdf_edit[0] in text
        urdf.write_text(text.replace(*urdf_edit))
    return path


@pytest.mark.parametrize("urdf_edit, changes, message", [
    (('<mass value="3.7"/>', '<mass value="0"/>'), {}, "gives no positive mass to what the joint shoulder_pan_joint moves"),
    (('<parent link="base_link"/>', '<parent link="nowhere"/>'), {}, "is not a robot model Pinocchio reads: "),
    (('name="shoulder_pan_joint"', ""), {}, "is not a robot model Pinocchio reads: "),
    (None, {"tool_frames": {"hand": "no_such_frame", "flange": "tool0"}}, "has no frame no_such_frame (its tool frame)"),
    (None, {"tool_frames": {"hand": "base_link", "flange": "tool0"}}, "tool frame base_link is on the fixed base"),
    (('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), {}, "gives a joint-space inertia that is not finite and positive definite"),
])
def test_a_model_its_urdf_or_tool_frame_cannot_give_is_one_line_of_bad_input(tmp_path, capfd, urdf_edit, changes, message):
    """A URDF that Pinocchio's parser refuses (its urdfdom messages, written by C++ on the
    process's stderr, kept off it), a link the joints move without a mass, a tool frame missing
    from the URDF or on the fixed base (no joint moves the contact: J = 0): one line of bad input
    on the command line, nothing else on stderr."""
    path = _my_arm(tmp_path, urdf_edit, **changes)
    with pytest.raises(BadInputError, match=re.escape(message)):
        RobotModel(path)
    code, out, err = run(capfd, "postures", "--robot", str(path))
    one_line_bad_input(code, out, err, message.split(":")[0].split(" (")[0])


@pytest.mark.parametrize("bad, match", [(np.nan, "non-finite"), ("a", "real numbers"), (None, "must have")])
def test_frames_of_a_bad_state_are_bad_input(bad, match):
    for robot in (RobotModel("panda"), RobotModel("g1")):
        q = np.full(robot.nq - 1, 0.0) if bad is None else np.full(robot.nq, bad, dtype=object)
        for method in (robot.frame_placements, robot.contact_jacobian6, robot.sole_corners):
            with pytest.raises(InvalidStateError, match=match):
                method(q)


@pytest.mark.parametrize("opening", [float("nan"), -0.01, 5.0])
def test_a_finger_opening_outside_the_fingers_limits_is_bad_input(opening):
    with pytest.raises(BadInputError, match="the finger opening must lie in"):
        RobotModel("panda", finger_opening=opening)


def test_contact_joints_that_cannot_move_the_contact_point_are_bad_input():
    """A standing robot whose contact joints (those its approach moves, the held contacts still)
    are one knee cannot move its hand along a wall's normal: refused when the model loads (its
    scripted approach never reached the wall, an internal error)."""
    g1 = ROBOTS["g1"]
    knee = replace(g1, contact=replace(g1.contact, joints=("left_knee_joint",)))
    with pytest.raises(BadInputError, match=r"contact joints \(left_knee_joint\) cannot move its contact point"):
        RobotModel(knee)
