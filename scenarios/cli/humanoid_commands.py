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
write their trials as a G1 dataset (``sim.humanoid_dataset``, docs/dataset.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.floating_base import METHODS, FloatingBaseModel, predict
from impactqp.controller.model.humanoid_stance import stance_posture
from impactqp.controller.model.robot_description import RobotDescription
from impactqp.controller.model.validation import BadInputError, approach_speed, tangential_velocity, unit_normal
from impactqp.controller.model.validation import restitution as restitution_coefficient
from impactqp.scenarios.cli.arguments import check_jobs, gif_output, output_directory, parse_vector

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


def trial_json(robot: str, trial) -> dict:
    """A trial of the floating-base robot named ``robot`` as JSON (sim.humanoid_trial.ImpactTrial)."""
    return {
        "robot": robot, "posture": trial.stance, "reference_speed": trial.speed, "contact_speed": trial.contact_speed,
        "impulse": trial.impulse.tolist(), "floor_impulse": trial.floor_impulse.tolist(),
        "impact_duration": trial.duration, "dq_jump": trial.measured_jump.tolist(),
        "com_jump": trial.measured_com_jump.tolist(),
        "predicted": {m: dv.tolist() for m, dv in trial.predicted_jump.items()},
        "predicted_com_jump": {m: c.tolist() for m, c in trial.predicted_com_jump.items()},
        "errors": trial.errors, "foot_slip": trial.foot_slip, "foot_lift": trial.foot_lift, "fell": trial.fell,
        "max_velocity_ratio": trial.max_velocity_ratio, "first_failure": trial.first_failure,
        "violated": not trial.feasible,
    }


def g1_simulate(
    choice: RobotChoice, posture: str, speed: float, files: dict, controller: str = "scripted"
) -> tuple[dict, str | None]:
    """One trial of the floating-base robot of ``choice`` (``sim.humanoid_trial``) driven by the
    scripted command or (``controller="qp"``) the whole-body QP with the ``--jump-model``
    predictor (crb, gm or classical), optionally rendered to a GIF (``files["video_file"]``) and
    added to the G1 dataset in ``files["out_dir"]``; its JSON (with the QP: ``controller`` and
    ``cycles_not_ok`` added) and the id of the trial written (None without ``out_dir``)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.video import render_humanoid_gif
    from impactqp.sim.humanoid_dataset import open_dataset, write_trials
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
    dataset = None if out_dir is None else open_dataset(output_directory(out_dir, "--out"))
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


def _campaign_trial(task):
    """One campaign trial in a worker process (robot description, stance, speed) -> ImpactTrial."""
    # lazy: a worker process imports the simulation when it runs its first trial
    from impactqp.sim.humanoid_trial import run_impact_trial

    robot, stance, speed = task
    return run_impact_trial(FloatingBaseModel(robot), robot.stances[stance], speed)


def g1_campaign(choice: RobotChoice, postures_text, speeds_text, jobs: int, out_dir: str) -> tuple[dict, str]:
    """The campaign of the floating-base robot of ``choice`` (``scenarios.humanoid_campaign``):
    Table I's JSON and the Markdown table, both written to ``out_dir`` (table1.json, table1.md)
    beside the campaign's trials as a G1 dataset (dataset.json and per trial its CSV and force
    CSV, ``sim.humanoid_dataset``)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.measured.atomic import write_atomic
    from impactqp.scenarios.humanoid_campaign import DEFAULT_SPEEDS, campaign_table, crb_reduction, mean_errors
    from impactqp.sim.humanoid_dataset import open_dataset, write_trials
    from impactqp.sim.process_pool import map_in_processes

    reject_options(["tangential_text", "plant_file", "tool"])
    stances = stance_names(choice.robot, postures_text)
    speeds = DEFAULT_SPEEDS if speeds_text is None else tuple(parse_vector(speeds_text, None, "--speeds").tolist())
    for v in speeds:
        approach_speed(v, "every speed of --speeds")
    out = output_directory(out_dir, "--out")
    dataset = open_dataset(out)
    trials = map_in_processes(_campaign_trial, [(choice.robot, s, v) for s in stances for v in speeds], check_jobs(jobs))
    errors = {m: e for m, e in mean_errors(trials).items() if m in METHODS}
    rows = [
        {**{k: v for k, v in trial_json(choice.robot.name, t).items() if k not in ("predicted", "predicted_com_jump", "robot")},
         "trial": i, "normal_speed": t.speed, "tangential_speed": 0.0, "average_error": t.errors,
         "crb_reduction_percent": 100.0 * (1.0 - t.errors["crb"] / t.errors["classical"]),
         "measured_jump": t.measured_jump.tolist()}
        for i, t in enumerate(trials)
    ]
    table = {"robot": choice.robot.name, "methods": list(METHODS), "rows": rows, "mean_average_error": errors,
             "mean_crb_reduction_percent": crb_reduction(errors)}
    text = campaign_table(trials)
    out.mkdir(parents=True, exist_ok=True)
    write_trials(dataset, trials)
    write_atomic(out / "table1.json", lambda tmp: Path(tmp).write_text(json.dumps(table, indent=2, allow_nan=False)))
    write_atomic(out / "table1.md", lambda tmp: Path(tmp).write_text(text + "\n"))
    return table, text
