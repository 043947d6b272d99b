"""Plant parameters: validated JSON overrides that change the MuJoCo physics as expected."""

import json
import pickle

import numpy as np
import pinocchio as pin
import pytest

from conftest import JOINTS
from impactqp.controller.model.jump import JUMP_MODELS
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.robot import PandaModel
from impactqp.controller.measured.impact import measure_impact
from impactqp.sim.plant import PAYLOAD_BODY, PlantParameterError, PlantParameters
from impactqp.sim.runner import TrialSpec, run_approach
from impactqp.sim.scene import build_scene

ROBOT = PandaModel()
Q = PANDA.postures["elbow_up"].q


def test_json_round_trip_is_atomic(tmp_path):
    plant = PlantParameters(armature=[0.1] * JOINTS, payload_mass=0.4, payload_com=[0.0, 0.0, -0.03],
                            friction=0.3, servo_gain=12.0)
    path = tmp_path / "plant.json"
    plant.to_json(path)
    assert PlantParameters.from_json(path) == plant
    assert [p.name for p in tmp_path.iterdir()] == ["plant.json"]


def test_partial_file_keeps_the_defaults(tmp_path):
    path = tmp_path / "plant.json"
    path.write_text(json.dumps({"payload_mass": 1.5}))
    plant = PlantParameters.from_json(path)
    assert plant.payload_mass == 1.5 and plant.armature == PlantParameters().armature


@pytest.mark.parametrize(
    "values, message",
    [
        ({"armatur": [0.0] * JOINTS}, "unknown plant parameter.*'armatur'"),
        ({"armature": [0.1] * JOINTS, "joint_damping": [0.1] * (JOINTS - 1)}, "one value per joint each"),
        ({"joint_damping": [0.1] * 6 + [-0.1]}, r"joint_damping\[6\] must lie in \[0, 500\] N m s/rad, got -0.1"),
        ({"payload_mass": -1.0}, "payload_mass"),
        ({"payload_com": [0.0, 0.0]}, "payload_com must be 3 numbers"),
        ({"friction": -0.1}, "friction"),
        ({"contact_solref": [-1000.0, -10.0]}, "negative solref"),
        ({"contact_solimp": [0.9, 0.95, 0.001]}, "contact_solimp must be 5 numbers"),
        ({"contact_solimp": [0.99, 0.9, 0.001, 0.5, 2]}, "dmin <= dmax"),
        ({"servo_gain": 0.0}, "servo_gain"),
        ({"armature": "heavy"}, "armature"),
        # physical ranges (issue 13): a Panda's payload rating plus margin, bounded gains and damping
        ({"payload_mass": 1e6}, r"payload_mass must lie in \[0, 5\] kg, got 1000000.0"),
        ({"payload_mass": True}, "payload_mass must be a number"),
        ({"armature": [True] + [0.0] * 6}, "armature must be a vector of numbers"),
        ({"armature": [1e9] + [0.0] * 6}, r"armature\[0\] must lie in \[0, 10\] kg m\^2, got 1000000000.0"),
        ({"joint_damping": [1e6] * JOINTS}, r"joint_damping\[0\]"),
        ({"payload_com": [0.0, 0.0, 5.0]}, r"payload_com\[2\]"),
        ({"friction": 1e9}, r"friction must lie in \[0, 2\], got 1000000000.0"),
        ({"servo_gain": 1e9}, "servo_gain"),
        ({"servo_stiffness": [0.0] * JOINTS}, r"servo_stiffness\[0\] must lie in \[1, 100000\] N m/rad"),
        ({"contact_solref": [100.0, 1.0]}, "time constant in"),
        ({"joint_friction": [-0.1] * JOINTS}, r"joint_friction\[0\] must lie in \[0, 50\] N m"),
        ({"link_inertials": {"panda_link3": [1.0] * 9}}, "must be 10 numbers"),
        ({"link_inertials": {"panda_link3": [-1.0, 0, 0, 0, 0.1, 0.1, 0.1, 0, 0, 0]}}, "mass of link panda_link3"),
        ({"link_inertials": {"panda_link3": [1.0, 0, 0, 0, 0.1, 0.1, 0.3, 0, 0, 0]}}, "is not a body's"),
        ({"link_inertials": {"panda_link3": [1.0, 0, 0, 0, 0.1, 0.1, 0.1, 0.2, 0, 0]}}, "is not a body's"),
        ({"link_inertials": [["panda_link3"]]}, "map link names to 10 numbers"),
    ],
)
def test_bad_overrides_are_rejected_with_clear_messages(tmp_path, values, message):
    path = tmp_path / "plant.json"
    path.write_text(json.dumps(values))
    with pytest.raises(PlantParameterError, match=message):
        PlantParameters.from_json(path)


def test_a_per_joint_vector_needs_one_value_per_joint_of_the_robot(tmp_path):
    """A plant file does not know its robot: a per-joint vector of the wrong size is refused when
    the plant meets the robot (its scene)."""
    path = tmp_path / "plant.json"
    path.write_text(json.dumps({"armature": [0.1] * (JOINTS - 1)}))
    plant = PlantParameters.from_json(path)
    with pytest.raises(PlantParameterError, match=f"armature must be {JOINTS} numbers"):
        plant.for_joints(JOINTS)
    with pytest.raises(PlantParameterError, match=f"armature must be {JOINTS} numbers"):
        build_scene(plant=plant)
    assert PlantParameters().for_joints(JOINTS).armature == (0.0,) * JOINTS  # nominal at every joint
    with pytest.raises(PlantParameterError, match=f"servo_stiffness must be {JOINTS} numbers"):
        build_scene(plant=PlantParameters(servo_stiffness=(3000.0,) * (JOINTS - 1)))
    assert PlantParameters().for_joints(JOINTS).servo_stiffness == ()  # none: the computed-torque servo


def test_unreadable_files_are_plant_parameter_errors(tmp_path):
    """The reader's failures (tests/test_files.py) come as the plant's own kind of bad input."""
    with pytest.raises(PlantParameterError, match="plant parameter file .* does not exist"):
        PlantParameters.from_json(tmp_path / "missing.json")
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(PlantParameterError, match="JSON object"):
        PlantParameters.from_json(tmp_path / "list.json")


def test_parameters_reach_the_mujoco_model():
    armature = np.linspace(0.1, 0.7, JOINTS)
    plant = PlantParameters(armature=armature, joint_damping=[0.5] * JOINTS, payload_mass=0.8,
                            payload_com=[0.0, 0.01, -0.02], friction=0.4,
                            contact_solref=(0.01, 1.2), contact_solimp=(0.9, 0.95, 0.002, 0.5, 2.0))
    scene = build_scene(plant=plant)
    model = scene.model
    np.testing.assert_allclose(model.dof_armature, armature)
    np.testing.assert_allclose(model.dof_damping, 0.5)
    assert model.body(PAYLOAD_BODY).mass[0] == pytest.approx(0.8)
    assert model.pair_friction[0][0] == pytest.approx(0.4)
    np.testing.assert_allclose(model.pair_solref[0], (0.01, 1.2))
    np.testing.assert_allclose(model.pair_solimp[0], (0.9, 0.95, 0.002, 0.5, 2.0))
    # M = M_links + diag(armature) + the payload, a point mass on the contact frame
    scene.set_state(Q, np.zeros(JOINTS))
    M_pin = pin.crba(ROBOT.model, ROBOT.data, Q)
    M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
    hand = ROBOT.contact_frame(Q)
    payload = hand.translation + hand.rotation @ np.array([0.0, 0.01, -0.02])
    np.testing.assert_allclose(scene.data.xipos[model.body(PAYLOAD_BODY).id], payload, atol=1e-9)
    J = pin.computeFrameJacobian(ROBOT.model, ROBOT.data, Q, ROBOT.contact_frame_id,
                                 pin.LOCAL_WORLD_ALIGNED)
    offset = hand.rotation @ np.array([0.0, 0.01, -0.02])
    J_payload = J[:3] - pin.skew(offset) @ J[3:]
    expected = M_pin + np.diag(armature) + 0.8 * J_payload.T @ J_payload
    np.testing.assert_allclose(scene.mass_matrix(), expected, atol=1e-9)


def _impact(plant):
    log = run_approach(build_scene(plant=plant), ROBOT, TrialSpec("test", Q, 0.15)).log
    return measure_impact(log)


def test_armature_shrinks_the_wrist_jumps_relative_to_classical():
    """Rotor inertia the classical model ignores resists the light wrist joints most."""
    ratios = []
    for armature in (0.0, 0.3):
        impact = _impact(PlantParameters(armature=[armature] * JOINTS))
        terms = ROBOT.terms(impact.q_pre, impact.dq_pre)
        classical = JUMP_MODELS["classical"].predict(terms, DEFAULT_WALL.normal, None,
                                                    impulse=impact.impulse).dq_jump
        ratios.append(np.abs(impact.dq_jump[4:]) / np.abs(classical[4:]))
    assert np.all(ratios[0] > 0.8)
    assert np.all(ratios[1] < 0.6 * ratios[0])


def test_payload_raises_the_impulse():
    bare = _impact(PlantParameters())
    loaded = _impact(PlantParameters(payload_mass=1.0))
    n = DEFAULT_WALL.normal
    assert loaded.impulse @ n > 1.2 * (bare.impulse @ n) > 0.0


def link_inertial(robot: PandaModel, joint: int, mass_scale: float) -> tuple[list[float], pin.Inertia]:
    """The link moved by ``joint`` (1-based) with its mass and inertia scaled by ``mass_scale``:
    the plant's 10 numbers (m, c, inertia about c) and Pinocchio's inertia of the same body."""
    inertia = robot.model.inertias[joint]
    scaled = pin.Inertia(mass_scale * inertia.mass, inertia.lever, mass_scale * inertia.inertia)
    I = scaled.inertia
    return [scaled.mass, *scaled.lever, I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]], scaled


@pytest.mark.parametrize("joint, scale", [(3, 1.0), (3, 1.7), (5, 0.4)])
def test_link_inertials_replace_a_links_inertial_as_pinocchio_would(joint, scale):
    """A link's inertial given to the plant: MuJoCo's joint-space inertia equals Pinocchio's with
    the same body changed (its own values leave M as it was)."""
    robot = PandaModel()
    values, inertia = link_inertial(robot, joint, scale)
    scene = build_scene(plant=PlantParameters(link_inertials={f"panda_link{joint}": values}))
    model = robot.model.copy()
    model.inertias[joint] = inertia
    data = model.createData()
    scene.set_state(Q, np.zeros(JOINTS))
    np.testing.assert_allclose(scene.mass_matrix(), pin.crba(model, data, Q), atol=1e-9)


def test_a_link_the_robot_does_not_have_is_bad_input():
    plant = PlantParameters(link_inertials={"link_nine": [1.0, 0, 0, 0, 0.1, 0.1, 0.1, 0, 0, 0]})
    with pytest.raises(PlantParameterError, match="the robot has no link 'link_nine'; its links: .*panda_link3"):
        build_scene(plant=plant)
    assert PlantParameters.from_dict(plant.to_dict()) == plant  # the JSON form reads back


def test_the_identified_panda_is_a_built_in_plant_of_joint_friction():
    """The Panda as identified by Gaz et al.: its link inertials are the URDF's already, so the
    built-in plant is the URDF with their joint friction (a dry friction per joint, half the
    identified sigmoid's range: between 0.1 and 0.7 N m); an unknown name lists the built-ins."""
    plant = PlantParameters.named("identified_panda")
    assert plant == PlantParameters(joint_friction=plant.joint_friction)
    assert len(plant.joint_friction) == JOINTS and all(0.1 < f < 0.7 for f in plant.joint_friction)
    np.testing.assert_array_equal(build_scene(plant=plant).model.dof_frictionloss[:JOINTS], plant.joint_friction)
    with pytest.raises(PlantParameterError, match="no built-in plant 'ideal'; built-in: identified_panda"):
        PlantParameters.named("ideal")


def test_the_physical_plant_keeps_the_physics_and_drops_the_sensor():
    faulty = PlantParameters(armature=(0.1,) * 7, sensor_delay=2.0, sensor_velocity_scale=1.1,
                             sensor_torque_offset=(0.5,) * 7, sensor_velocity_step=(0.004,) * 7)
    physical = faulty.physical()
    assert physical == PlantParameters(armature=(0.1,) * 7)
    assert physical.physical() is physical and faulty.physical() is physical  # made once
    assert faulty != physical and hash(physical) == hash(PlantParameters(armature=(0.1,) * 7))
    again = pickle.loads(pickle.dumps(faulty))  # the way to a diagnosis' worker processes
    assert again == faulty and again.physical() == physical
