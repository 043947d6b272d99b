"""``predict``, ``simulate`` and ``campaign`` with ``--robot g1`` (``max-speed``: ``scenarios.cli.max_speed_command``): the standing
floating-base G1 hitting a wall with its right hand (docs/floating-base.md).

Each command receives the ``RobotChoice`` of a floating-base robot (``choice.robot.floating``)
and builds its model from the description (``FloatingBaseModel(choice.robot)``); the JSON's
``robot`` is the description's name. The G1's postures are its stances (its description's
``stances``); the wall stands
2 cm in front of the stance's hand, normal -x (5 cm with ``simulate --controller qp``: the
whole-body QP drives the trial, ``sim.humanoid_qp_source``). An option of the arm's command that
has no meaning for the G1 (a tool, a plant file, a wall point, jump constraints: only
``simulate --controller qp`` runs a QP, and takes ``--jump-model``) is bad input when given: one
line naming it. The JSON keeps the arm's keys where they mean the same and
adds the G1's (CoM jump, foot wrenches, slip, lift, fall). ``simulate --out DIR`` and ``campaign``
write their trials as a G1 dataset (``sim.generation``, docs/dataset.md); ``campaign`` is
the arm's command, given the floating-base robot's trial runner (``scenarios.humanoid_campaign``).
"""

from __future__ import annotations


import click
import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel, predict
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.robot_description import RobotDescription
from impactqp.controller.model.validation import BadInputError, approach_speed, tangential_velocity, unit_normal
from impactqp.controller.model.validation import restitution as restitution_coefficient
from impactqp.scenarios.cli.arguments import gif_output, output_directory, parse_vector

def reject_options(names) -> None:
    """Bad input when one of the options ``names`` (click parameter names) was given."""
    ctx = click.get_current_context()
    for name in names:
        if ctx.get_parameter_source(name) not in (None, click.core.ParameterSource.DEFAULT):
            option = next(p for p in ctx.command.params if p.name == name).opts[0]
            raise BadInputError(f"{option} does not apply to --robot g1 (docs/floating-base.md)")


def stance_names(robot: RobotDescription, text: str | None) -> tuple[str, ...]:
    """Comma-separated stance names of ``robot`` (all when None), each checked."""
    stances = robot.stances
    names = tuple(stances) if text is None else tuple(s.strip() for s in text.split(","))
    for name in names:
        if name not in stances:
            raise BadInputError(f"unknown posture {name!r} for the {robot.name}; known: {', '.join(stances)}")
    return names


def g1_predict(choice: RobotChoice, posture: str | None, q_text: str | None, impact: dict, methods) -> dict:
    """The ``predict`` report of the floating-base robot of ``choice`` (feet held): per method
    (``methods``; None: classical, gm, crb) the jump dq_jump (nv: base twist, joints), impulse,
    CoM jump and feet wrenches."""
    reject_options(["tool"])
    robot = FloatingBaseModel(choice.robot)
    if (posture is None) == (q_text is None):
        raise BadInputError("give exactly one of --posture NAME or --q Q1,...,Q36")
    stances = choice.robot.stances
    q = (stance_posture(robot, stances[stance_names(choice.robot, posture)[0]]) if posture
         else parse_vector(q_text, robot.model.nq, "--q"))
    normal = unit_normal(parse_vector(impact["normal_text"], 3, "--normal"), "--normal")
    speed = approach_speed(impact["speed"], "--speed")
    tangential = (np.zeros(3) if impact["tangential_text"] is None
                  else tangential_velocity(parse_vector(impact["tangential_text"], 3, "--tangential"), normal, "--tangential"))
    c_r = restitution_coefficient(impact["restitution"], "--restitution")
    v_minus = -speed * normal + tangential
    terms = robot.terms(q)
    report = {
        "robot": choice.robot.name, "q": terms.q.tolist(), "contact_point": terms.contact_point.tolist(),
        "normal": normal.tolist(),
        "pre_impact_velocity": v_minus.tolist(), "restitution": c_r, "cond_M": float(np.linalg.cond(terms.M)),
        "methods": {},
    }
    for method in METHODS if methods is None else methods:
        jump = predict(terms, method, normal, v_minus, c_r)
        report["methods"][method] = {
            "dq_jump": jump.dv.tolist(), "impulse": jump.impulse.tolist(), "com_jump": jump.com_jump.tolist(),
            "feet_impulse": jump.feet_impulse.tolist(),
        }
    return report


def g1_simulate(
    choice: RobotChoice, posture: str, speed: float, files: dict, controller: str = "scripted"
) -> tuple[dict, str | None]:
    """One trial of the floating-base robot of ``choice`` (``sim.humanoid_trial``) driven by the
    scripted command or (``controller="qp"``) the whole-body QP with the ``--jump-model``
    predictor (crb, gm or classical), optionally rendered to a GIF (``files["video_file"]``) and
    added to the G1 dataset in ``files["out_dir"]``; its JSON (with the QP: ``controller`` and
    ``cycles_not_ok`` added) and the id of the trial written (None without ``out_dir``)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.humanoid_campaign import trial_json
    from impactqp.scenarios.video import render_humanoid_gif
    from impactqp.sim.generation import open_dataset, write_trials
    from impactqp.sim.humanoid_qp_source import QpCommand
    from impactqp.sim.humanoid_trial import SCRIPTED, run_impact_trial

    reject_options(["tangential_text", "no_jump_constraint", "plant_file", "wall_point", "wall_normal",
                    "tool"] + (["jump_model"] if controller == "scripted" else []))
    video_file, out_dir = files["video_file"], files["out_dir"]
    source = SCRIPTED
    if controller == "qp":
        method = click.get_current_context().params["jump_model"]
        if method not in METHODS:
            raise BadInputError(f"--jump-model {method} is not a floating-base predictor; choose from {', '.join(METHODS)}")
        source = QpCommand(method=method)
    stance = choice.robot.stances[stance_names(choice.robot, posture)[0]]
    approach_speed(speed, "--speed")
    if video_file is not None:
        gif_output(video_file)
    dataset = None if out_dir is None else open_dataset(output_directory(out_dir, "--out"), choice.robot)
    robot = FloatingBaseModel(choice.robot)
    trial = run_impact_trial(robot, stance, speed, source=source)
    written = None if dataset is None else write_trials(dataset, [trial])[0].id
    if video_file is not None:
        render_humanoid_gif(robot, trial, video_file)
    report = trial_json(choice.robot.name, trial)
    if controller == "qp":
        report.update(controller="qp", jump_model=source.method, cycles_not_ok=trial.record.not_ok)
    return report, written


def simulate_text(report: dict) -> str:
    """A floating-base robot's trial report as text."""
    return "\n".join([
        f"{report['posture']} ({report['robot']}): commanded {report['reference_speed']} m/s, contact speed "
        f"{report['contact_speed']:.4f} m/s, impulse {np.round(report['impulse'], 4).tolist()} N s",
        "errors (26): " + ", ".join(f"{m} {e:.4f}" for m, e in report["errors"].items()),
        f"foot slip {1e3 * report['foot_slip']:.2f} mm, lift {1e3 * report['foot_lift']:.2f} mm, fell: {report['fell']}, "
        f"max |dq|/dq_max {report['max_velocity_ratio']:.3f}, failed first: {report['first_failure'] or '-'}",
    ] + ([f"whole-body QP ({report['jump_model']}): {report['cycles_not_ok']} cycles not OK"]
         if report.get("controller") == "qp" else []))


