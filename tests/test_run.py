"""``scenarios.run``: the default configuration of a run; ``--robot`` chooses the model and, in
simulation, the scene."""

from impactqp.controller.model.robot_description import ROBOTS
from impactqp.scenarios.run import RunRequest, contact_start, controller_config, run


def test_the_default_configuration_approaches_the_posture_wall():
    config = controller_config(RunRequest(posture="elbow_up", speed=0.1))
    assert config.post_impact.mode == "retract"
    assert config.tasks[0].params["speed"] == 0.1


def test_a_simulated_fr3_run_uses_the_fr3_model_and_scene_and_detects_the_contact():
    request = RunRequest(robot="fr3", speed=0.15, duration=0.6, unpaced=True)
    report, result = run(request)
    session = result.session
    assert session.robot.description is ROBOTS["fr3"]
    t_contact = contact_start(result)  # the FR3 scene's own contact force
    assert t_contact is not None and report["impact"]["detected"]
    assert 0.0 <= report["impact"]["time"] - t_contact <= 5e-3
    assert report["watchdog_trips"] == 0 and report["phase"] == "stop"
