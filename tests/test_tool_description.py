"""Tool descriptions: the built-ins against the Franka Hand's URDF geometry and inertia, files in
JSON and TOML, and every field validated."""

import json
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from conftest import FRANKA_ARMS
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model.robot import RobotModel
from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.tool_description import (
    TOOLS,
    Pad,
    Sphere,
    ToolDescription,
    tool_description,
    tool_from_dict,
)
from impactqp.controller.model.validation import BadInputError


def fingertip_boxes(robot):
    """World-of-the-hand boxes (lower corner, upper corner) of the closed fingers' rubber tips,
    read from the robot's URDF: each finger's last collision box, placed by its joint origin."""
    root = ET.parse(robot.urdf_path()).getroot()
    joints = {j.find("child").get("link"): j for j in root.findall("joint")}
    boxes = []
    for name in robot.finger_links:
        joint_origin = joints[name].find("origin")
        placement = pin.SE3(pin.rpy.rpyToMatrix(*map(float, joint_origin.get("rpy", "0 0 0").split())),
                            np.array(list(map(float, joint_origin.get("xyz").split()))))
        tip = root.find(f"link[@name='{name}']").findall("collision")[-1]
        centre = placement.act(np.array(list(map(float, tip.find("origin").get("xyz").split()))))
        half = np.abs(placement.rotation @ (np.array(list(map(float, tip.find("geometry/box").get("size").split()))) / 2))
        boxes.append((centre - half, centre + half))
    return boxes


@pytest.mark.parametrize("robot", FRANKA_ARMS)
def test_franka_hand_touches_with_the_closed_fingertips_of_the_urdf(robot):
    (lo1, hi1), (lo2, hi2) = fingertip_boxes(ROBOTS[robot])
    low, high = np.minimum(lo1, lo2), np.maximum(hi1, hi2)
    hand = TOOLS["franka_hand"]
    pad = hand.geometry
    assert hand.frame == "hand" and hand.replaces_hand
    assert hand.contact_point[2] == pytest.approx(high[2], abs=1e-9)  # the farthest point up the axis
    np.testing.assert_allclose(pad.centre + pad.normal * pad.size[2] / 2, [0.0, 0.0, high[2]], atol=1e-9)
    np.testing.assert_allclose(pad.size, high - low, atol=5e-5)  # the two tips meet on the axis


def test_franka_hand_inertia_is_the_pandas_urdf_hand_with_closed_fingers():
    """example-robot-data's Panda carries franka_description's Franka Hand: replacing it by the
    franka_hand tool leaves the arm's inertia unchanged."""
    q = ROBOTS["panda"].postures["elbow_left"].q
    with_urdf_hand, with_tool = RobotModel("panda", "impact_tip"), RobotModel("panda", "franka_hand")
    a, b = with_urdf_hand.terms(q), with_tool.terms(q)
    np.testing.assert_allclose(b.M, a.M, atol=1e-12)
    assert b.mass == pytest.approx(a.mass, abs=1e-12)
    np.testing.assert_allclose(b.inertia_com, a.inertia_com, atol=1e-12)


def test_builtin_tools_round_trip_through_a_dict():
    for tool in TOOLS.values():
        again = tool_from_dict(json.loads(json.dumps(tool.as_dict())))
        assert again.as_dict() == tool.as_dict()


def test_a_tool_file_in_json_or_toml(tmp_path):
    tool = TOOLS["pad"]
    json_file = tmp_path / "my_pad.json"
    json_file.write_text(json.dumps({key: value for key, value in tool.as_dict().items() if key != "name"}))
    from_json = tool_description(json_file)
    assert from_json.name == "my_pad"
    np.testing.assert_allclose(from_json.inertia, tool.inertia)
    toml_file = tmp_path / "hammer.toml"
    toml_file.write_text(
        'frame = "flange"\nreplaces_hand = true\ncontact_point = [0.0, 0.0, 0.15]\nmass = 0.5\n'
        'com = [0.0, 0.0, 0.1]\ninertia = [[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-4]]\n'
        '[geometry]\nshape = "sphere"\nradius = 0.03\ncentre = [0.0, 0.0, 0.12]\n'
    )
    hammer = tool_description(str(toml_file))
    assert (hammer.name, hammer.frame, hammer.mass, hammer.geometry.radius) == ("hammer", "flange", 0.5, 0.03)
    upper = tmp_path / "HAMMER.TOML"  # a suffix in capitals is the same file type
    upper.write_text(toml_file.read_text())
    assert tool_description(str(upper)).as_dict() == {**hammer.as_dict(), "name": "HAMMER"}


@pytest.mark.parametrize("text, message", [
    ("{", "not valid JSON"),
    ("[]", "must be a JSON object"),
    ('{"frame": "hand"}', "missing keys"),
    ('{"frame": "hand", "geometry": {"shape": "sphere", "radius": 0.02, "centre": [0, 0, 0.1]},'
     ' "contact_point": [0, 0, 0.12], "colour": "red"}', "unknown keys"),
    ('{"frame": "hand", "geometry": {"shape": "cube", "size": 1}, "contact_point": [0, 0, 0.12]}', "shape"),
    ('{"frame": "hand", "geometry": {"shape": "sphere", "radius": 0.02}, "contact_point": [0, 0, 0.12]}',
     "exactly the keys"),
    ('{"frame": "hand", "geometry": {"shape": "sphere", "radius": 0.02, "centre": [0, 0, 0.1]},'
     ' "contact_point": [0, 0, 0.12], "mass": 0.3}', "centre of mass"),
])
def test_bad_tool_files_are_bad_input(tmp_path, text, message):
    path = tmp_path / "tool.json"
    path.write_text(text)
    with pytest.raises(BadInputError, match=message):
        tool_description(path)


def test_a_missing_file_a_directory_or_unknown_name_is_bad_input(tmp_path):
    with pytest.raises(BadInputError, match="tool file .* does not exist"):
        tool_description(tmp_path / "absent.toml")
    (tmp_path / "folder.json").mkdir()
    with pytest.raises(BadInputError, match="is a directory"):
        tool_description(tmp_path / "folder.json")
    with pytest.raises(BadInputError, match="impact_tip, franka_hand, pad"):
        tool_description("hammer")


SPHERE = Sphere(0.02, (0.0, 0.0, 0.12))


@pytest.mark.parametrize("change, message", [
    (dict(frame="wrist"), "tool frame"),
    (dict(name=""), "name"),
    (dict(replaces_hand=1), "replaces_hand"),
    (dict(contact_point=(0.0, 0.0, 0.13)), "contact surface"),
    (dict(contact_point=(0.0, 0.0, 0.6)), "within 0.5 m"),
    (dict(mass=-0.1), "tool mass"),
    (dict(mass=3.5), "tool mass"),
    (dict(mass=float("nan")), "tool mass"),
    (dict(mass=0.0, inertia=np.eye(3) * 1e-3), "massless"),
    (dict(inertia=np.diag([1e-3, 1e-3, 3e-3])), "rigid body"),
    (dict(inertia=np.diag([-1e-3, 1e-3, 1e-3])), "rigid body"),
    (dict(inertia=np.array([[1e-3, 1e-4, 0], [0, 1e-3, 0], [0, 0, 1e-3]])), "symmetric"),
    (dict(inertia=np.eye(2)), "3x3"),
    (dict(inertia=np.eye(3) * 1e300), "exceeds what a 0.2 kg tool"),
    (dict(inertia=np.eye(3) * 0.21), "exceeds what a 0.2 kg tool"),
    (dict(com=(0.0, np.inf, 0.0)), "finite"),
])
def test_every_field_is_validated(change, message):
    fields = dict(name="t", frame="hand", replaces_hand=False, geometry=SPHERE, contact_point=(0.0, 0.0, 0.14),
                  mass=0.2, com=(0.0, 0.0, 0.1), inertia=np.eye(3) * 1e-4)
    with pytest.raises(BadInputError, match=message):
        ToolDescription(**{**fields, **change})


@pytest.mark.parametrize("args, message", [
    ((0.0, (0, 0, 0.1)), "radius"),
    ((0.02, (0, 0, 1.0)), "within 0.5 m"),
])
def test_bad_spheres(args, message):
    with pytest.raises(BadInputError, match=message):
        Sphere(*args)


@pytest.mark.parametrize("args, message", [
    (((0.1, 0.1, 0.0), (0, 0, 0.05), (0, 0, 1)), "pad length"),
    (((0.1, 0.1), (0, 0, 0.05), (0, 0, 1)), "pad size"),
    (((0.1, 0.1, 0.01), (0, 0, 0.05), (0, 0, 0)), "pad normal"),
])
def test_bad_pads(args, message):
    with pytest.raises(BadInputError, match=message):
        Pad(*args)


unit = st.lists(st.floats(-1, 1), min_size=3, max_size=3).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.2)


@settings(max_examples=40, deadline=None)
@given(normal=unit, u=st.floats(-0.5, 0.5), v=st.floats(-0.5, 0.5), lift=st.floats(-0.01, 0.01))
def test_pad_face_points_are_on_the_surface_and_others_are_not(normal, u, v, lift):
    pad = Pad((0.06, 0.04, 0.01), (0.0, 0.0, 0.05), normal)
    R = pad.rotation
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R[:, 2], pad.normal, atol=1e-12)
    on_face = pad.centre + R @ np.array([u * 0.06, v * 0.04, 0.005])
    assert pad.surface_distance(on_face) == pytest.approx(0.0, abs=1e-12)
    assert pad.surface_distance(on_face + lift * pad.normal) == pytest.approx(abs(lift), abs=1e-12)


def test_tools_are_read_only():
    with pytest.raises(ValueError):
        TOOLS["pad"].inertia[0, 0] = 1.0
    with pytest.raises(AttributeError):
        TOOLS["pad"].mass = 1.0  # frozen
    assert replace(TOOLS["pad"], mass=0.5).mass == 0.5


@settings(max_examples=30, deadline=None)
@given(normal=unit, corner=st.lists(st.sampled_from([-0.5, 0.5]), min_size=3, max_size=3))
def test_bounding_radius_reaches_every_corner_and_no_farther(normal, corner):
    pad = Pad((0.06, 0.04, 0.01), (0.0, 0.0, 0.05), normal)
    point = pad.centre + pad.rotation @ (np.array(corner) * pad.size)
    assert np.linalg.norm(point - pad.centre) == pytest.approx(pad.bounding_radius, abs=1e-12)
    assert SPHERE.bounding_radius == SPHERE.radius


@settings(max_examples=30, deadline=None)
@given(normal=unit, direction=unit)
def test_lowest_is_the_smallest_projection_over_the_geometry(normal, direction):
    """u . x over the pad's corners (a box's extreme points) and over the sphere's surface
    (centre + radius w for unit w): the smallest is ``lowest(u)``, reached at a corner / at
    w = -u/|u|, and no sampled point goes below it."""
    pad = Pad((0.06, 0.04, 0.01), (0.0, 0.0, 0.05), normal)
    corners = [pad.centre + pad.rotation @ ((np.array(c) - 0.5) * pad.size) for c in np.ndindex(2, 2, 2)]
    assert pad.lowest(direction) == pytest.approx(min(direction @ c for c in corners), abs=1e-12)
    w = np.random.default_rng(0).normal(size=(500, 3))
    points = SPHERE.centre + SPHERE.radius * w / np.linalg.norm(w, axis=1)[:, None]
    assert np.min(points @ direction) >= SPHERE.lowest(direction) - 1e-12
    deepest = SPHERE.centre - SPHERE.radius * direction / np.linalg.norm(direction)
    assert direction @ deepest == pytest.approx(SPHERE.lowest(direction), abs=1e-12)
