"""ControllerConfig: files, round trips and the controller it builds."""

from pathlib import Path

import numpy as np
import pytest

from conftest import JOINTS, g1_model
from impactqp.controller.config import ControllerConfig, TaskConfig, build_controller, post_impact_config
from impactqp.controller.model.postures import DEFAULT_WALL, Surface
from impactqp.controller.model.robot_description import PANDA
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.qp import ImpactAwareController
from impactqp.tasks import ContactApproachTask, DampingTask, PostureTask

TOML = """
dt = 0.002
solver = "daqp"

[[tasks]]
type = "contact_approach"
speed = 0.12
tangential_velocity = [0.0, 0.05, 0.0]
tangential_weight = 50.0

[[tasks]]
type = "damping"
gain = 2.0

[limits]
torque = false
velocity_scale = 0.9

[impact]
jump_model = "robust"
restitution = 0.3
impact_duration = 0.02

[surface]
point = [0.7, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
"""

YAML = """
dt: 0.002
solver: daqp
tasks:
  - type: contact_approach
    speed: 0.12
    tangential_velocity: [0.0, 0.05, 0.0]
    tangential_weight: 50.0
  - type: damping
    gain: 2.0
limits:
  torque: false
  velocity_scale: 0.9
impact:
  jump_model: robust
  restitution: 0.3
  impact_duration: 0.02
surface:
  point: [0.7, 0.0, 0.0]
  normal: [-1.0, 0.0, 0.0]
"""


def test_toml_and_yaml_files_give_the_same_configuration(tmp_path):
    (tmp_path / "c.toml").write_text(TOML)
    (tmp_path / "c.yaml").write_text(YAML)
    from_toml = ControllerConfig.from_file(tmp_path / "c.toml")
    assert from_toml == ControllerConfig.from_file(tmp_path / "c.yaml")
    assert from_toml.dt == 0.002 and from_toml.impact.jump_model == "robust"
    assert from_toml.tasks[0] == TaskConfig(
        "contact_approach", {"speed": 0.12, "tangential_velocity": [0.0, 0.05, 0.0], "tangential_weight": 50.0}
    )


def test_configuration_round_trips_through_a_dict():
    config = ControllerConfig.approach(DEFAULT_WALL, 0.2, jump_model="gm", restitution=0.4)
    assert ControllerConfig.from_dict(config.to_dict()) == config


def test_build_controller_follows_the_file(robot, tmp_path):
    (tmp_path / "c.toml").write_text(TOML)
    controller = build_controller(ControllerConfig.from_file(tmp_path / "c.toml"), robot)
    names = [c.name for c in controller.constraints]
    assert "joint_torque_limit" not in names
    for model in ("crb", "gm", "classical"):
        assert f"post_impact_velocity[{model}]" in names and f"impulsive_torque[{model}]" in names
    assert controller.dt == 0.002 and controller.solver.name == "daqp"
    approach = controller.tasks[0]
    assert isinstance(approach, ContactApproachTask) and np.allclose(approach.normal, [-1.0, 0.0, 0.0])
    assert np.allclose(approach.reference_velocity, [0.12, 0.05, 0.0])
    velocity = next(c for c in controller.constraints if c.name == "joint_velocity_limit")
    assert np.allclose(velocity.dq_max, 0.9 * robot.dq_max)
    impulsive = next(c for c in controller.constraints if c.name == "impulsive_torque[gm]")
    np.testing.assert_allclose(impulsive.impulse_limit, robot.tau_max * 0.02)  # tau_max delta_t
    assert impulsive.impact.restitution == 0.3


def test_default_approach_configuration(robot):
    surface = Surface([0.65, 0.0, 0.0], [-1.0, 0.0, 0.0])
    controller = build_controller(ControllerConfig.approach(surface, 0.1), robot)
    assert isinstance(controller, ImpactAwareController)
    assert [type(t) for t in controller.tasks] == [ContactApproachTask, PostureTask, DampingTask]
    assert {c.name for c in controller.constraints} == {
        "joint_acceleration_limit", "joint_position_limit", "joint_velocity_limit", "joint_torque_limit",
        "post_impact_velocity[crb]", "impulsive_torque[crb]",
    }
    command = controller.step(PANDA.postures["elbow_up"].q, np.zeros(JOINTS))
    assert command.status == "ok"


def test_no_jump_model_switches_the_impact_constraints_off_but_keeps_the_prediction(robot):
    controller = build_controller(ControllerConfig.approach(DEFAULT_WALL, 0.1, jump_model=None), robot)
    assert not any("impact" in c.name for c in controller.constraints)
    assert controller.impact.name == "crb"


@pytest.mark.parametrize(
    "data",
    [
        {"unknown": 1},
        {"impact": {"jump_model": "newton"}},
        {"limits": {"position": True, "jerk": 2}},
        {"tasks": [{"type": "teleport"}]},
        {"tasks": [{"type": "damping", "stiffness": 3.0}]},
        {"limits": {"acceleration_scale": 3.0}},
        {"limits": {"velocity_scale": float("nan")}},
        {"impact": {"lookahead_distance": float("nan")}},
        {"impact": {"impact_duration": 0.0}},
        {"impact": {"restitution": 1.5}},
        {"tasks": [{"type": "damping"}, {"type": "contact_approach", "speed": float("nan")}]},
        {"tasks": [{"type": "damping"}, {"type": "posture", "stiffness": float("nan")}]},
        {"tasks": [{"type": "damping", "gain": float("inf")}]},
        {"tasks": [{"type": "damping"}, {"type": "frame", "position_weight": -1.0}]},
    ],
)
def test_bad_configurations_are_rejected_with_a_value_error(robot, data):
    with pytest.raises(ValueError):
        build_controller(ControllerConfig.from_dict({"tasks": [{"type": "damping"}]} | data), robot)


@pytest.mark.parametrize(
    "data, fragment",
    [
        ({"dt": float("nan")}, "dt must lie in [0.0001, 0.01] s"),
        ({"dt": "fast"}, "dt must be a number"),
        ({"dt": 10}, "dt must lie in"),
        ({"dt": True}, "dt must be a number"),
        ({"limits": {"jerk_scale": 1e-300}}, "limits.jerk_scale must lie in [0.01, 1]"),
        ({"limits": {"position": "yes"}}, "limits.position must be true or false"),
        ({"limits": {"position_margin": 3.0}}, "limits.position_margin"),
        ({"impact": {"jump_model": 5}}, "impact.jump_model"),
        ({"impact": {"lookahead_time": 1e9}}, "impact.lookahead_time"),
        ({"impact": {"always_active": 1}}, "impact.always_active"),
        ({"post_impact": {"hold_depth": 1.0}}, "post_impact.hold_depth"),
        ({"surface": {"friction": "x"}}, "the surface friction"),
        ({"surface": {"point": "abc"}}, "the surface point"),
        ({"solver": 5}, "solver"),
        ({"tasks": 5}, "tasks must be a list"),
        ({"tasks": [5]}, "tasks[0] must be a table"),
        ({"tasks": [{"type": ["damping"]}]}, "task type"),
        ({"tasks": [{"type": "damping", "params": 5}]}, "tasks[0].params must be a table"),
        ({"limits": 5}, "[limits] must be a table"),
        ({"robot": "kuka"}, "unknown robot 'kuka'; choose from panda, fr3, ur5, g1"),
        ({"robot": 3}, "robot must be a robot name"),
        ({"tool": "hammer"}, "unknown tool 'hammer'"),
        ({"tool": 5}, "tool must be a tool name, a tool file or a [tool] table"),
        ({"tool": {"frame": "wrist"}}, "[tool]: tool description: unknown keys [], missing keys"),
        ({"impact": {"friction": 2.5}}, "impact.friction"),
        ({"impact": {"friction": -0.1}}, "impact.friction"),
        ({"impact": {"friction": 0.3, "pyramid_edges": 2}}, "impact.pyramid_edges"),
        ({"impact": {"friction": 0.3, "pyramid_edges": 17}}, "impact.pyramid_edges"),
        ({"impact": {"friction_rows": "cone"}}, "impact.friction_rows"),
        ({"impact": {"friction": 0.3, "jump_model": "classical_normal"}}, "impact.friction"),
        ({"tasks": [{"type": "damping", "gian": 1.0}]}, "tasks[0]: bad parameters for the damping task"),
        ({"tasks": [{"type": "damping", "gain": -1.0}]}, "tasks[0]: damping gain must lie in"),
        ({"tasks": [{"type": "damping"}, {"type": "contact_approach", "speed": "fast"}]}, "tasks[1]: the approach speed"),
        ({"tasks": [{"type": "damping"}, {"type": "contact_approach", "speed": -0.1}]}, "tasks[1]: the approach speed"),
        ({"tasks": [{"type": "frame", "weight": float("inf")}]}, "tasks[0]: bad parameters for the frame task"),
        ({"tasks": [{"type": "frame", "target_rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}]},
         "tasks[0]: target_rotation must be a rotation matrix"),
        ({"tasks": [{"type": "frame", "target_rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}]},
         "tasks[0]: target_rotation must be a rotation matrix"),
    ],
)
def test_bad_values_are_bad_input_that_names_the_key(data, fragment):
    with pytest.raises(BadInputError) as caught:
        ControllerConfig.from_dict(data)
    assert fragment in str(caught.value)


@pytest.mark.parametrize(
    "name, content, fragment",
    [
        ("c.yaml", b"- 1\n- 2\n", "must be a table"),  # the reader's failures (tests/test_files.py)
        ("c.toml", b"[limits]\njerk_scale = 1e-300\n", "limits.jerk_scale"),
    ],
)
def test_bad_files_are_bad_input_that_names_the_file(tmp_path, name, content, fragment):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(BadInputError) as caught:
        ControllerConfig.from_file(path)
    assert fragment in str(caught.value) and str(path) in str(caught.value)


def test_build_controller_refuses_what_is_not_a_configuration_or_a_model_of_its_kind_of_base(robot):
    config = ControllerConfig.approach(DEFAULT_WALL, 0.3, robot="panda")
    with pytest.raises(BadInputError, match="needs a ControllerConfig"):
        build_controller(config.to_dict(), robot)
    with pytest.raises(BadInputError, match="must be a RobotModel"):
        build_controller(config, "panda")
    with pytest.raises(BadInputError, match="a fixed-base arm's .* and the model a floating-base robot's"):
        build_controller(config, g1_model())
    for speed in ("0.3", True, np.array([0.3])):
        with pytest.raises(BadInputError, match="the approach speed must be a number"):
            ControllerConfig.approach(DEFAULT_WALL, speed, robot="panda")


def test_task_parameters_of_the_wrong_type_are_bad_input(robot):
    for params in ({"gain": "x"}, {"gain": 1e300}, {"stiffness": 1.0}):
        with pytest.raises(BadInputError, match="damping"):
            build_controller(ControllerConfig.from_dict({"tasks": [{"type": "damping", **params}]}), robot)



@pytest.mark.parametrize("task", [
    {"type": "contact_approach", "speed": 0.1},
    {"type": "surface_offset", "offset": 0.05, "normal": [-1.0, 0.0, 0.0], "surface_point": [0.6, 0.0, 0.0]},
])
def test_a_tasks_orientation_parameters_are_its_orientation_hold(robot, task):
    """``orientation_stiffness``, ``orientation_damping`` and ``orientation_weight`` of a task in
    the file set its orientation rows: a_ang* = k_R log(R* R^T) - d_R w, weighted; each bad one,
    or an ``orientation`` key, is bad input naming it."""
    hold = {"orientation_stiffness": 80.0, "orientation_damping": 5.0, "orientation_weight": 3.0}
    built = build_controller(ControllerConfig.from_dict({"tasks": [task | hold]}), robot).tasks[0]
    assert (built.orientation_stiffness, built.orientation_damping) == (80.0, 5.0)
    np.testing.assert_array_equal(built.weight[3:], [3.0, 3.0, 3.0])
    default = build_controller(ControllerConfig.from_dict({"tasks": [task | {"orientation_stiffness": 64.0}]}), robot)
    assert default.tasks[0].orientation_damping == 16.0  # 2 sqrt(k_R)
    for key in hold:
        with pytest.raises(BadInputError, match=key):
            build_controller(ControllerConfig.from_dict({"tasks": [task | {key: -1.0}]}), robot)
    with pytest.raises(BadInputError, match="orientation_stiffness, orientation_damping, orientation_weight"):
        build_controller(ControllerConfig.from_dict({"tasks": [task | {"orientation": 1.0}]}), robot)

def test_unsupported_file_type(tmp_path):
    (tmp_path / "c.json").write_text("{}")
    with pytest.raises(ValueError):
        ControllerConfig.from_file(tmp_path / "c.json")


def test_post_impact_section_loads_and_is_validated(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[post_impact]\nmode = "hold"\nhold_depth = 0.0005\n')
    config = ControllerConfig.from_file(path)
    assert config.post_impact.mode == "hold" and config.post_impact.hold_depth == 0.0005
    assert ControllerConfig.from_dict(config.to_dict()) == config
    bad_sections = (
        {"mode": "bounce"}, {"retract_distance": -0.01}, {"max_speed": float("nan")},
        {"mode": "hold", "hold_depth": 0.0}, {"mode": "hold", "hold_speed": 0.0}, {"hold_speed": float("inf")},
    )
    for bad in bad_sections:
        with pytest.raises(ValueError, match="post_impact"):
            ControllerConfig.from_dict({"post_impact": bad})


@pytest.mark.parametrize("mode", ["retract", "hold", "continue"])
def test_post_impact_controller_has_no_impact_constraints_and_keeps_the_limits(robot, mode):
    config = ControllerConfig.approach(DEFAULT_WALL, 0.15)
    config.post_impact.mode = mode
    post = post_impact_config(config)
    assert post.impact.jump_model is None and post.limits == config.limits
    names = [c.name for c in build_controller(post, robot).constraints]
    before = [c.name for c in build_controller(config, robot).constraints]
    impact_aware = ("post_impact_velocity", "impulsive_torque")
    assert any(name.startswith(impact_aware) for name in before)
    assert not any(name.startswith(impact_aware) for name in names)
    assert "joint_velocity_limit" in names
    types = [t.type for t in post.tasks]
    if mode == "continue":
        assert types == [t.type for t in config.tasks]
    else:
        assert types[0] == "surface_offset" and "contact_approach" not in types
        params, post_impact = post.tasks[0].params, config.post_impact
        if mode == "retract":
            assert (params["offset"], params["max_speed"]) == (post_impact.retract_distance, post_impact.max_speed)
        else:
            assert (params["offset"], params["max_speed"]) == (-post_impact.hold_depth, post_impact.hold_speed)


def test_the_robot_and_the_tool_of_a_file_build_the_controller(tmp_path):
    """``robot`` and a ``[tool]`` table: the controller's model is that robot carrying that tool,
    with that robot's limits."""
    from impactqp.controller.model.tool_description import TOOLS

    path = tmp_path / "c.toml"
    path.write_text('robot = "fr3"\n[[tasks]]\ntype = "damping"\n[tool]\nframe = "hand"\ncontact_point = [0.0, 0.0, 0.14]\n'
                    '[tool.geometry]\nshape = "sphere"\nradius = 0.02\ncentre = [0.0, 0.0, 0.12]\n')
    config = ControllerConfig.from_file(path)
    assert config.choice.robot.name == "fr3"
    assert config.choice.tool.as_dict() == {**TOOLS["impact_tip"].as_dict(), "name": "tool"}
    controller = build_controller(config)
    assert controller.robot.description.name == "fr3"
    np.testing.assert_array_equal(controller.robot.dq_max, config.choice.robot.dq_max)
    assert ControllerConfig().choice.is_default


# ---------------------------------------------------------------- a floating base: the G1's preset
def test_the_floating_base_preset_holds_the_balance_and_the_feet_and_refuses_a_bad_controller():
    """The G1's approach: the hand's approach, the CoM, the torso's orientation, the posture and
    the damping; the joints' limits, the feet's rows, the post-impact velocities and the capture
    region, the feet's wrenches at the impact, no torque rows."""
    import whole_body_states as g1

    c = g1.controller("staggered", method="gm")
    assert [x.name for x in c.constraints] == [
        "joint_acceleration_limit", "joint_position_limit", "joint_velocity_limit", "held_contacts",
        "post_impact_velocity[gm]", "capture_region[gm]", "foot_wrench[gm]",
    ]
    assert [t.name for t in c.tasks] == ["contact_approach", "com", "frame[torso]", "posture", "damping"]
    assert c.tasks[3].rows == g1.robot().n_joints and c.tasks[4].rows == g1.robot().nv
    with pytest.raises(BadInputError):
        type(c)(g1.robot(), [], c.constraints, 0.001)
    with pytest.raises(BadInputError):
        type(c)(g1.robot(), [DampingTask(variables=g1.robot().nv)], c.constraints + c.constraints[-1:], 0.001)
    robust = g1.controller("parallel", method="robust")
    assert sum(x.name.startswith("capture_region") for x in robust.constraints) == 3
    assert sum(x.name.startswith("foot_wrench") for x in robust.constraints) == 3


@pytest.mark.parametrize("key", ["limits.torque", "impact.impulsive_torque"])
def test_torque_rows_on_a_floating_base_are_bad_input_that_names_the_key(key):
    section, name = key.split(".")
    data = {"robot": "g1", "limits": {"torque": False}, "impact": {"impulsive_torque": False}}
    data[section][name] = True
    with pytest.raises(BadInputError, match=key.replace(".", r"\.")):
        ControllerConfig.from_dict(data)


@pytest.mark.parametrize("method", ["crb", "classical"])
def test_the_g1s_friction_rows_are_built_and_hold_at_the_qps_solution_over_a_closed_loop_approach(method):
    """``impact.friction`` on a robot standing on held contacts: the post-impact velocity rows of
    every edge, and every vertex's capture-region and feet rows (``EdgeCaptureRegionLimit``,
    ``EdgeFootWrenchLimit``), (1 + edges) blocks each; over a closed-loop approach every row the
    state does not already violate holds at each cycle's solution."""
    import whole_body_states as g1

    q = g1.stance("parallel")
    data = {"robot": "g1", "limits": {"torque": False},
            "impact": {"jump_model": method, "impulsive_torque": False, "friction": 0.3, "always_active": True},
            "surface": {"point": g1.wall_ahead(q, 0.1).point.tolist(), "normal": g1.NORMAL.tolist(), "friction": 0.3},
            "tasks": ControllerConfig.approach(g1.wall_ahead(q, 0.1), 0.3, robot="g1").to_dict()["tasks"]}
    config = ControllerConfig.from_dict(data)
    controller = build_controller(config, g1.robot(), q)
    frictionless = build_controller(ControllerConfig.from_dict({**data, "impact": {**data["impact"], "friction": 0.0}}),
                                    g1.robot(), q)
    rows = {type(x).__name__: x.rows for x in controller.constraints if x.relaxed}
    plain = {type(x).__name__: x.rows for x in frictionless.constraints if x.relaxed}
    assert rows == {"PostImpactVelocityLimit": 5 * plain["PostImpactVelocityLimit"],
                    "EdgeCaptureRegionLimit": 5 * plain["CaptureRegionLimit"],
                    "EdgeFootWrenchLimit": 5 * plain["FootWrenchLimit"]}
    v = np.zeros(g1.robot().nv)
    controller.reset(q, v)
    for _ in range(40):
        command = controller.step(q, v)
        assert not command.is_fallback, command.message
        terms = g1.robot().terms(q, v)
        for constraint in (x for x in controller.constraints if x.relaxed):
            C, lower, upper = np.zeros((constraint.rows, g1.robot().nv)), np.zeros(constraint.rows), np.zeros(constraint.rows)
            constraint.compute_into(terms, controller._row_cycle, C, lower, upper)
            kept = (lower <= 0.0) & (upper >= 0.0)  # rows the state does not already violate
            assert np.all((C @ command.ddq)[kept] <= upper[kept] + 1e-6), constraint.name
            assert np.all((C @ command.ddq)[kept] >= lower[kept] - 1e-6), constraint.name
        q, v = command.q_cmd, command.dq_cmd
    assert -g1.NORMAL @ g1.robot().terms(q, v).J @ v > 0.01  # it approached


def test_the_floating_base_after_the_impact_keeps_its_torso_task():
    import whole_body_states as g1

    q = g1.stance("parallel")
    config = ControllerConfig.approach(g1.wall_ahead(q), 0.3, robot="g1")
    post = post_impact_config(config)
    assert [t.type for t in post.tasks] == ["surface_offset", "centre_of_mass", "frame", "posture", "damping"]
    controller = build_controller(post, g1.robot(), q)
    assert "held_contacts" in [x.name for x in controller.constraints]
    assert not any(x.relaxed for x in controller.constraints)  # the impact and capture rows are off


def documented_toml(page: str) -> str:
    """The TOML block of a docs page."""
    text = (Path(__file__).parent.parent / "docs" / page).read_text()
    return text.split("```toml\n", 1)[1].split("```", 1)[0]


@pytest.mark.parametrize("rows, blocks", [("pyramid", 5), ("slip", 4)])
def test_the_documented_friction_rows_file_builds_the_stacked_rows(robot, tmp_path, rows, blocks):
    """The TOML example of docs/frictional-impacts.md loads, and its controller stacks one block of
    post-impact velocity and impulsive torque rows per edge under the frictionless block."""
    path = tmp_path / "friction.toml"
    path.write_text(documented_toml("frictional-impacts.md").replace('friction_rows = "pyramid"', f'friction_rows = "{rows}"'))
    config = ControllerConfig.from_file(path)
    assert (config.impact.friction, config.impact.pyramid_edges, config.impact.friction_rows) == (0.3, 4, rows)
    controller = build_controller(config, robot)
    counts = {c.name: c.rows for c in controller.constraints}
    assert counts["post_impact_velocity[crb]"] == counts["impulsive_torque[crb]"] == blocks * JOINTS
    assert ControllerConfig.from_dict(config.to_dict()) == config
    frictionless = build_controller(ControllerConfig.from_dict({**config.to_dict(), "impact": {"friction": 0.0}}), robot)
    assert {c.name: c.rows for c in frictionless.constraints}["post_impact_velocity[crb]"] == JOINTS
