"""``scenarios.run``: the default configuration of a run; ``--robot`` chooses the model and, in
simulation, the scene."""

from impactqp.controller.model.robot_description import ROBOTS
from impactqp.controller.model.choice import RobotChoice
from impactqp.scenarios.run import RunRequest, contact_start, controller_config, run


def test_the_default_configuration_approaches_the_posture_wall():
    config = controller_config(RunRequest(posture="elbow_up", speed=0.1))
    assert config.post_impact.mode == "retract"
    assert config.tasks[0].params["speed"] == 0.1


def test_a_simulated_fr3_run_uses_the_fr3_model_and_scene_and_detects_the_contact():
    request = RunRequest(choice=RobotChoice.of("fr3", "impact_tip"), speed=0.15, duration=0.6, unpaced=True)
    report, result = run(request)
    session = result.session
    assert session.robot.description is ROBOTS["fr3"]
    t_contact = contact_start(result)  # the FR3 scene's own contact force
    assert t_contact is not None and report["impact"]["detected"]
    assert 0.0 <= report["impact"]["time"] - t_contact <= 5e-3
    assert report["watchdog_trips"] == 0 and report["phase"] == "stop"


def test_the_configuration_carries_the_robot_and_the_tool_of_the_request(tmp_path):
    """Without --config the configuration is the request's robot and tool (a tool file's full
    description); a configuration file decides, and a --robot/--tool that disagrees with it is
    bad input."""
    import json

    import pytest

    from impactqp.controller.config import ControllerConfig
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.controller.model.tool_description import TOOLS
    from impactqp.controller.model.validation import BadInputError

    fr3_hand = RobotChoice.of("fr3", "franka_hand")
    config = controller_config(RunRequest(choice=fr3_hand))
    assert (config.robot, config.tool) == ("fr3", "franka_hand")
    assert ControllerConfig.from_dict(config.to_dict()).choice.same_as(fr3_hand)
    tool_file = tmp_path / "hammer.json"
    tool_file.write_text(json.dumps({**TOOLS["pad"].as_dict(), "name": "hammer"}))
    config = controller_config(RunRequest(choice=RobotChoice.of("panda", str(tool_file))))
    assert config.tool["name"] == "hammer" and config.choice.tool.as_dict()["mass"] == TOOLS["pad"].mass
    (tmp_path / "c.toml").write_text('robot = "fr3"\ntool = "hammer.json"\n')
    config = controller_config(RunRequest(config_file=str(tmp_path / "c.toml")))
    assert config.choice.robot.name == "fr3" and config.choice.tool.name == "hammer"
    with pytest.raises(BadInputError, match=r"the configuration \(fr3, hammer\) differ from --robot/--tool"):
        controller_config(RunRequest(config_file=str(tmp_path / "c.toml"), choice=RobotChoice.of("panda", "pad")))
