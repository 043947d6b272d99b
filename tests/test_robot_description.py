"""Robot descriptions: the registry, limits inside each URDF's, the URDF edit for a hand-replacing
tool, the named postures' properties on each arm, and a user's own description file."""

import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from impactqp.controller.model.files import read_mapping
from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS, description_from_mapping, model_urdf, robot_description
from impactqp.controller.model.tool_description import TOOLS
from impactqp.controller.model.validation import BadInputError

POSTURE_MARGIN = 0.1
"""rad: the least distance of a named posture's joints from the limits."""
MIN_SINGULAR_RATIO = 0.05
"""sigma_min / sigma_max of J at a named posture: far from singular."""
ARMS = [name for name in ROBOTS if not ROBOTS[name].floating]
FRANKA_ARMS = [name for name in ARMS if ROBOTS[name].finger_joints]


def urdf_joint_limits(robot):
    """(lower, upper, velocity, effort) of the robot's moving joints, read from its URDF file."""
    root = ET.parse(robot.urdf_path()).getroot()
    joints = {j.get("name"): j.find("limit") for j in root.findall("joint")}
    return np.array([[float(joints[name].get(k)) for k in ("lower", "upper", "velocity", "effort")]
                     for name in robot.joints]).T


@pytest.mark.parametrize("name", ARMS)
def test_limits_lie_inside_the_urdf_limits(name):
    robot = robot_description(name)
    lower, upper, velocity, effort = urdf_joint_limits(robot)
    assert np.all(lower <= robot.q_min) and np.all(robot.q_min < robot.q_max) and np.all(robot.q_max <= upper)
    assert np.all(0.0 < robot.dq_max) and np.all(robot.dq_max <= velocity)
    assert np.all(0.0 < robot.tau_max) and np.all(robot.tau_max <= effort)
    assert np.all(robot.ddq_max > 0.0) and np.all(robot.dddq_max > 0.0)
    # the model uses the description's limits
    model = RobotModel(name)
    np.testing.assert_array_equal(model.q_min, robot.q_min)
    np.testing.assert_array_equal(model.dddq_max, robot.dddq_max)


def test_descriptions_are_read_only():
    with pytest.raises(ValueError):
        ROBOTS["fr3"].dq_max[0] = 10.0


def test_unknown_robot_lists_the_choices():
    with pytest.raises(BadInputError, match="panda, fr3, ur5, g1"):
        robot_description("kuka")
    assert robot_description(ROBOTS["fr3"]) is ROBOTS["fr3"]


def test_unknown_posture_names_the_robot():
    with pytest.raises(BadInputError, match="fr3.*elbow_up"):
        ROBOTS["fr3"].posture("elbow_down")


def test_the_fr3_has_the_pandas_kinematic_chain():
    """Why the FR3 shares the Panda's named postures: equal joint placements and hand frame."""
    panda, fr3 = RobotModel("panda"), RobotModel("fr3")
    for i in range(1, 8):
        assert panda.model.jointPlacements[i].isApprox(fr3.model.jointPlacements[i], 1e-12)
    assert panda.model.frames[panda.hand_frame_id].placement.isApprox(fr3.model.frames[fr3.hand_frame_id].placement, 1e-12)


@pytest.mark.parametrize("name", ARMS)
def test_named_postures_touch_the_wall_inside_the_limits_away_from_singularities(name):
    model = RobotModel(name)
    for posture in model.description.postures.values():
        terms = model.terms(posture.q)
        assert posture.surface.signed_distance(terms.contact_point) == pytest.approx(0.0, abs=1e-6)
        np.testing.assert_allclose(terms.contact_rotation[:, 2], -posture.surface.normal, atol=1e-5)
        assert np.all(posture.q - model.q_min >= POSTURE_MARGIN) and np.all(model.q_max - posture.q >= POSTURE_MARGIN)
        sigma = np.linalg.svd(terms.J, compute_uv=False)
        assert sigma[-1] >= MIN_SINGULAR_RATIO * sigma[0]


@pytest.mark.parametrize("name", FRANKA_ARMS)
def test_named_postures_differ_in_elbow_and_wrist_arrangement(name):
    q = {key: p.q for key, p in ROBOTS[name].postures.items()}
    assert q["elbow_right"][2] < 0.0 < q["elbow_left"][2]  # elbow swung right / left (q3)
    assert q["elbow_right"][4] < 0.0 < q["elbow_left"][4]  # wrist rolled down / up (q5)
    assert abs(q["elbow_up"][2]) < 0.1 and abs(q["elbow_up"][4]) < 0.1  # sagittal elbow, neutral wrist


@pytest.mark.parametrize("name", FRANKA_ARMS)
def test_a_hand_replacing_tool_removes_the_fingers_and_the_hand_inertia(name):
    robot = ROBOTS[name]
    root = ET.fromstring(model_urdf(robot, TOOLS["pad"]))
    links = {link.get("name"): link for link in root.findall("link")}
    assert not set(robot.finger_links) & set(links)
    assert not set(robot.finger_joints) & {j.get("name") for j in root.findall("joint")}
    assert len(links[robot.hand_frame]) == 0  # no inertial, visual or collision left
    assert model_urdf(robot, TOOLS["impact_tip"]) == robot.urdf_path().read_text(encoding="utf-8")
    # the arm's own links keep their inertia: the model's mass drops by the hand's exactly
    hand_mass = sum(
        float(link.find("inertial/mass").get("value"))
        for link in ET.parse(robot.urdf_path()).getroot().findall("link")
        if link.get("name") in (robot.hand_frame, *robot.finger_links)
    )
    with_hand = sum(i.mass for i in RobotModel(name, "impact_tip").model.inertias)
    massless_pad = RobotModel(name, replace(TOOLS["pad"], mass=0.0, com=np.zeros(3), inertia=np.zeros((3, 3))))
    assert sum(i.mass for i in massless_pad.model.inertias) == pytest.approx(with_hand - hand_mass, abs=1e-12)


def test_an_fr3_without_franky_sim_is_bad_input(monkeypatch):
    import importlib.util

    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    with pytest.raises(BadInputError, match="franky-sim"):
        ROBOTS["fr3"].urdf_path()


def test_base_placement_moves_every_robot():
    R = pin.utils.rpyToMatrix(0.0, 0.0, 0.7)
    for name in ARMS:
        q = ROBOTS[name].postures["elbow_up"].q
        moved = RobotModel(name, base_placement=pin.SE3(R, np.zeros(3)))
        np.testing.assert_allclose(moved.contact_point(q), R @ RobotModel(name).contact_point(q), atol=1e-12)


def test_the_ur5_postures_differ_in_elbow_and_wrist_arrangement():
    """elbow_up / elbow_down: the elbow above / below the line from the shoulder to the wrist;
    wrist_flipped: the wrist turned under (q5 < 0) with the elbow up."""
    model = RobotModel("ur5")
    ids = [model.model.getJointId(name) for name in ("shoulder_lift_joint", "elbow_joint", "wrist_1_joint")]

    def elbow_height(q):
        pin.forwardKinematics(model.model, model.data, q)
        shoulder, elbow, wrist = (model.data.oMi[i].translation for i in ids)
        t = (elbow[:2] - shoulder[:2]) @ (wrist[:2] - shoulder[:2]) / np.sum((wrist[:2] - shoulder[:2]) ** 2)
        return elbow[2] - (shoulder[2] + t * (wrist[2] - shoulder[2]))

    postures = ROBOTS["ur5"].postures
    assert elbow_height(postures["elbow_up"].q) > 0.1 and elbow_height(postures["elbow_down"].q) < -0.1
    assert elbow_height(postures["wrist_flipped"].q) > 0.1 and postures["wrist_flipped"].q[4] < 0.0 < postures["elbow_up"].q[4]


def test_limits_missing_from_a_file_are_the_urdfs():
    robot = ROBOTS["ur5"]
    lower, upper, velocity, effort = urdf_joint_limits(robot)
    for ours, theirs in ((robot.q_min, lower), (robot.q_max, upper), (robot.dq_max, velocity), (robot.tau_max, effort)):
        np.testing.assert_array_equal(ours, theirs)
    assert robot.joints == tuple(RobotModel("ur5").model.names[1:])


def test_the_g1_description_gives_the_floating_models_joints_and_limits():
    g1, model = ROBOTS["g1"], RobotModel("g1")
    assert g1.floating and g1.joints == tuple(model.joint_names)
    for ours, theirs in ((g1.q_min, model.q_min), (g1.q_max, model.q_max), (g1.dq_max, model.dq_max), (g1.tau_max, model.tau_max)):
        np.testing.assert_array_equal(ours, theirs)
    assert [c.frame for c in g1.held_contacts] == [model.model.frames[i].name for i in model.held_frame_ids]
    assert {name: model.model.frames[i].name for name, i in model.frame_ids.items()} == dict(g1.frames) == {"torso": "torso_link"}
    with pytest.raises(BadInputError, match="carries no tool"):
        RobotModel("g1", "impact_tip")


@pytest.mark.parametrize("frames, message", [
    ({"torso": 3}, "frame torso must be a non-empty name"),
    ("torso_link", r"\[frames\] must be a table"),
])
def test_a_bad_frames_table_is_one_line_of_bad_input(frames, message):
    data = dict(read_mapping(ROBOTS["g1"].source, "the G1"), frames=frames)
    with pytest.raises(BadInputError, match=message):
        description_from_mapping(data, ROBOTS["g1"].source.parent, ROBOTS["g1"].source)


def test_a_named_frame_missing_from_the_urdf_is_bad_input():
    with pytest.raises(BadInputError, match="has no frame no_such_link"):
        RobotModel(replace(ROBOTS["g1"], frames={"torso": "no_such_link"}))


def _user_arm(folder, **changes):
    """A user's own arm in ``folder``: the UR5's URDF copied beside a TOML description that names
    it by a relative path, with ``changes`` to the description's keys (None removes a key)."""
    import shutil
    import tomllib

    ur5 = ROBOTS["ur5"]
    shutil.copy(ur5.urdf_path(), folder / "my_arm.urdf")
    data = tomllib.loads(ur5.source.read_text())
    data.update(name="my_arm", urdf="my_arm.urdf", meshes=str(ur5.mesh_dir()))
    for key, value in changes.items():
        data.pop(key) if value is None else data.__setitem__(key, value)
    path = folder / "my_arm.toml"
    path.write_text(_toml(data))
    return path


def _toml(data: dict, prefix: str = "") -> str:
    """A small TOML writer for the test's tables (strings, numbers, lists, nested tables)."""
    import json

    scalars = [f"{k} = {json.dumps(v)}" for k, v in data.items() if not isinstance(v, dict)]
    tables = [_toml(v, f"{prefix}{k}.") for k, v in data.items() if isinstance(v, dict)]
    head = f"[{prefix[:-1]}]\n" if prefix else ""
    return head + "\n".join(scalars) + "\n" + "\n".join(tables)


def test_a_users_own_arm_loads_from_its_file(tmp_path):
    path = _user_arm(tmp_path)
    robot = robot_description(str(path))
    assert robot.name == "my_arm" and robot.urdf_path() == tmp_path / "my_arm.urdf"
    ur5 = ROBOTS["ur5"]
    np.testing.assert_array_equal(robot.dq_max, ur5.dq_max)
    mine, theirs = RobotModel(path), RobotModel("ur5")
    q = ur5.postures["elbow_up"].q
    np.testing.assert_allclose(mine.terms(q).M, theirs.terms(q).M, atol=1e-14)
    assert mine.nv == len(robot.joints) == 6


@pytest.mark.parametrize("changes, message", [
    ({"limits": {}}, "needs ddq_max"),
    ({"limits": {"ddq_max": [1.0, 2.0], "dddq_max": 1.0}}, "ddq_max must be 6 numbers"),
    ({"limits": {"ddq_max": -1.0, "dddq_max": 1.0}}, "ddq_max must be > 0"),
    ({"limits": {"ddq_max": 1e6, "dddq_max": 7500.0}}, r"ddq_max must lie in \[0.1, 100000\] rad/s\^2 .* got 1e\+06"),
    ({"limits": {"ddq_max": 15.0, "dddq_max": 7500.0, "tau_max": 1e-3}}, r"tau_max must lie in \[0.1, 100000\] N m"),
    ({"limits": {"ddq_max": 15.0, "dddq_max": 7500.0, "dq_max": 1e308}}, r"dq_max must lie in \[0.01, 100\] rad/s"),
    ({"base": "wheeled"}, "base must be one of fixed, floating"),
    ({"urdf": None}, "needs 'urdf'"),
    ({"urdf": "missing.urdf"}, "does not exist"),
    ({"joints": ["shoulder_pan_joint", "no_such_joint"]}, "no moving joints no_such_joint"),
    ({"wheels": 4}, "unknown robot description keys wheels"),
    ({"default_posture": "elbow_sideways"}, "default_posture 'elbow_sideways'"),
    ({"postures": {"up": {"q": [0.0, 1.0]}}}, "posture up q must be 6 numbers"),
    ({"postures": {"up": {"q": [0.0, -1.6, 1.6, 0.0, 1.5, 100.0]}}, "default_posture": "up"},
     r"posture up: wrist_3_joint = 100.0000 rad lies outside its limits \[-6.2832, 6.2832\]"),
])
def test_a_bad_robot_file_is_one_line_of_bad_input(tmp_path, changes, message):
    path = _user_arm(tmp_path, **changes)
    with pytest.raises(BadInputError, match=message) as error:
        robot_description(path)
    assert "\n" not in str(error.value)


def test_the_standing_robot_s_own_data_come_from_its_description():
    """What a standing robot's tools read of it is data: the joints that move its contact point,
    its held contacts' labels and the posture its stance solver pulls towards."""
    from impactqp.controller.model.max_speed import contact_joints

    g1 = ROBOTS["g1"]
    assert contact_joints(g1) == g1.contact.joints and len(g1.contact.joints) == 7
    assert all(j.startswith("right_") for j in g1.contact.joints)
    assert [c.label for c in g1.held_contacts] == ["left", "right"]
    assert g1.nominal_posture["left_knee_joint"] == 0.6 and set(g1.nominal_posture) <= set(g1.joints)
    assert contact_joints(ROBOTS["panda"]) == ROBOTS["panda"].joints  # no contact joints named: every joint


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["contact"].update(joints=["no_such_joint"]), "are not its joints"),
    (lambda d: d.update(nominal_posture={"left_knee_joint": 9.0}), "nominal_posture left_knee_joint"),
    (lambda d: d.update(nominal_posture={"no_such_joint": 0.1}), "unknown keys no_such_joint"),
    (lambda d: d["held_contacts"][0].update(label=""), "label"),
])
def test_bad_standing_robot_data_are_one_line(edit, message):
    import tomllib
    from importlib.resources import files

    from impactqp.controller.model.robot_description import description_from_mapping

    data = tomllib.loads((files("impactqp.controller.model") / "robots" / "g1.toml").read_text())
    edit(data)
    with pytest.raises(BadInputError, match=message):
        description_from_mapping(data)


@pytest.mark.parametrize("edit, message", [
    (('lower="-6.28318530718"', 'lower="abc"'), "lower limit of joint shoulder_pan_joint is not a number: 'abc'"),
    (('ixx="0.00443333156"', 'ixx="-1"'), r"inertia of link .* is not a rigid body's \(principal moments -1"),
    (('izz="0.0072"', 'izz="0.1"'), r"A \+ B >= C"),
    (('izz="0.0072"', 'izz="nan"'), "is not finite"),
])
def test_a_urdf_with_a_bad_number_is_one_line_of_bad_input(tmp_path, edit, message):
    """A limit that is not a number, a link inertia no rigid body has (a negative principal
    moment, moments against the triangle inequality, NaN): bad input when the model loads, not
    an error of Pinocchio's parser or of the MuJoCo scene's compiler later."""
    path = _user_arm(tmp_path)
    urdf = tmp_path / "my_arm.urdf"
    text = urdf.read_text()
    assert edit[0] in text
    urdf.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(BadInputError, match=message) as error:
        RobotModel(path)
    assert "\n" not in str(error.value)
