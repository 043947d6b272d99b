"""``scenarios.run``: the default configuration of a run."""

from impactqp.scenarios.run import RunRequest, controller_config


def test_the_default_configuration_approaches_the_posture_wall():
    config = controller_config(RunRequest(posture="elbow_up", speed=0.1))
    assert config.post_impact.mode == "retract"
    assert config.tasks[0].params["speed"] == 0.1
