"""The simulation commands of ``impactqp``: ``simulate`` and ``campaign`` (``max-speed``:
``scenarios.cli.max_speed_command``), and the wall and plant options they share with it.

Every command validates its input before simulating; bad input (an unknown posture, a speed
<= 0, a bad plant file, a wall out of reach, ...) ends with one line on stderr and exit code 2
(``scenarios.cli.main``). Progress bars go to stderr and are off with ``--json``.

With ``--robot g1`` (a floating base, docs/floating-base.md) the trial is the standing robot's at a
stance of its description (:func:`stance_trial`): the wall 2 cm in front of the stance's hand,
normal -x (5 cm with ``simulate --controller qp``: the whole-body QP drives the trial,
``sim.trial_sources.QpCommand``). An option of the arm's command that has no meaning for it (a tool, a
plant file, a wall point, jump constraints: only ``--controller qp`` runs a QP, and takes
``--jump-model``) is bad input when given: one line naming it. The JSON keeps the arm's keys where
they mean the same and adds the G1's (CoM jump, foot wrenches, slip, lift, fall); ``--out DIR``
and ``campaign`` write its trials as a G1 dataset (``sim.generation``, docs/dataset.md).
"""

from __future__ import annotations

# First: MuJoCo's OpenGL backend is chosen when MuJoCo is first imported (scenarios.video).
from impactqp.scenarios import video  # noqa: F401, I001

from dataclasses import replace

import click
import numpy as np

from impactqp.constraints import JUMP_MODEL_CHOICES
from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.postures import DEFAULT_WALL, ImpactPosture, Surface
from impactqp.controller.model.validation import BadInputError, tangential_velocity, unit_normal
from impactqp.controller.model.validation import simulated_speed
from impactqp.scenarios.cli.arguments import (
    check_jobs,
    emit_json,
    load_plant,
    max_trials_option,
    output_directory,
    output_file,
    parse_list,
    parse_vector,
    reject_options,
    robot_options,
    stance_names,
    video_output,
)
from impactqp.scenarios.cli.stderr_log import show_progress

SIMULATE_START_DISTANCE = 0.05


# ---------------------------------------------------------------------------- shared options
def wall(point_text: str | None, normal_text: str | None) -> Surface:
    """The default wall, moved to --wall-point and/or turned to --wall-normal."""
    point = DEFAULT_WALL.point if point_text is None else parse_vector(point_text, 3, "--wall-point")
    normal = DEFAULT_WALL.normal if normal_text is None else unit_normal(parse_vector(normal_text, 3, "--wall-normal"), "--wall-normal")
    return Surface(point, normal, DEFAULT_WALL.friction)


def check_reachable(choice: RobotChoice, posture: ImpactPosture, surface: Surface, distance: float) -> None:
    """Reject a wall the posture of ``choice``'s robot and tool cannot face (before any process
    is started)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.inverse_kinematics import UnreachableStartError, approach_start

    try:
        approach_start(choice.shared_model, posture.q, surface, distance)
    except UnreachableStartError as error:
        raise BadInputError(str(error)) from None


wall_point_option = click.option("--wall-point", "wall_point", help="A point X,Y,Z (m) of the wall; default 0.6,0,0.")
wall_normal_option = click.option(
    "--wall-normal", "wall_normal", help="The wall normal NX,NY,NZ towards the robot; default -1,0,0."
)
plant_option = click.option("--plant", "plant_file", help="Plant: a JSON file of overrides (sim.plant) or a built-in name (identified_panda).")


# ---------------------------------------------------------------------------- simulate
@click.command()
@click.option("--posture", "posture_name", required=True, help="A named posture (see `impactqp postures`).")
@click.option("--speed", type=float, required=True, help="Reference approach speed along -normal (m/s), > 0.")
@click.option("--tangential", "tangential_text", help="Tangential velocity VX,VY,VZ (m/s), orthogonal to the wall normal.")
@click.option("--no-jump-constraint", is_flag=True, help="Switch the jump-aware constraints off.")
@click.option("--jump-model", type=click.Choice(list(JUMP_MODEL_CHOICES)), default="crb", show_default=True)
@click.option("--friction", type=float,
              help="mu in [0, 2]: the QP's robust friction rows (4-edge pyramid) and the wall's friction.")
@plant_option
@wall_point_option
@wall_normal_option
@click.option("--out", "out_dir", help="Add the trial to the dataset in this directory (controller.measured.dataset format).")
@click.option("--video", "video_file", help="Render the impact with the robot's meshes to this animated GIF (needs an offscreen GL backend).")
@click.option("--figure", "figure_file", help="Plot every joint's dq(t) around the impact, the predicted dq+ and the limits (.png, .pdf, .svg).")
@click.option("--view", is_flag=True, help="Replay the trial in MuJoCo's interactive viewer (needs a display).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--controller", "controller", type=click.Choice(["scripted", "qp"]),
              help="With --robot g1: the command source, the scripted arm command (default) or the whole-body QP.")
@robot_options(humanoid=True)
def simulate(posture_name, speed, tangential_text, plant_file, as_json, choice, **trial):
    """One approach-and-impact trial: the QP controller at 1 kHz drives the MuJoCo robot.

    The tool starts at rest 5 cm in front of the wall; the controller accelerates it towards the
    reference velocity (capped by the jump-aware constraints when they are on) until it hits.
    --friction MU: the jump-aware constraints get the robust friction rows of mu = MU and the
    wall's friction is MU too (docs/frictional-impacts.md).
    With --robot g1: the standing G1 (a stance) hits the wall with its right hand, kinematic
    control, driven by a scripted arm command or (--controller qp) by the whole-body QP
    (docs/floating-base.md).
    """
    controller = trial.pop("controller")
    friction = trial.pop("friction")
    if choice.robot.floating:
        report, written = stance_trial(choice, posture_name, speed, trial, controller or "scripted", friction)
        if as_json:
            emit_json(report)
        else:
            click.echo(stance_trial_text(report))
        if written is not None and not as_json:
            click.echo(f"trial {written} written to {trial['out_dir']}")
        return
    if controller is not None:
        raise BadInputError("--controller chooses the command source of --robot g1; the arm is always driven by its QP")
    # lazy: the command line loads what a command needs when it runs
    from impactqp.sim.generation import dataset_header
    from impactqp.scenarios.trial import TrialRunner
    from impactqp.sim.runner import TrialSpec
    from impactqp.controller.measured.dataset_writer import DatasetWriter
    from impactqp.scenarios.readable import fixed
    from impactqp.scenarios.impact_figure import ImpactLabel

    out_dir = trial["out_dir"]
    check_pictures(trial)
    posture = choice.posture(posture_name)
    simulated_speed(speed, "--speed")
    surface = wall(trial["wall_point"], trial["wall_normal"])
    tangential = (
        np.zeros(3) if tangential_text is None
        else tangential_velocity(parse_vector(tangential_text, 3, "--tangential"), surface.normal, "--tangential")
    )
    plant = load_plant(plant_file)
    if friction is not None:
        surface = frictional_wall(surface, friction, plant, trial["no_jump_constraint"], trial["jump_model"])
    writer = None
    if out_dir is not None:  # an existing dataset of another header, or with files in the way: refused before the trial
        writer = DatasetWriter(output_directory(out_dir, "--out"), dataset_header(surface, choice))
    check_reachable(choice, posture, surface, SIMULATE_START_DISTANCE)

    spec = TrialSpec(
        posture.name, posture.q, speed, tangential,
        jump_model=None if trial["no_jump_constraint"] else trial["jump_model"],
        start_at_rest=True, start_distance=SIMULATE_START_DISTANCE,
    )
    runner = TrialRunner.build(surface, plant, choice)
    if friction is not None and spec.jump_model is not None:
        runner.source = replace(runner.source_of(spec), friction=surface.friction)
    result = runner.run(spec)
    if writer is not None:
        writer.add_trial(*result.dataset_trial())
    write_pictures(runner, result, trial, ImpactLabel(choice.robot, choice.tool.name, posture.name))
    report = result.to_json()
    if as_json:
        emit_json(report)
        return
    click.echo(f"{posture.name}: reference {speed} m/s, jump constraints {report['jump_model'] or 'off'}")
    click.echo(f"contact speed    {report['contact_speed']:.4f} m/s at t = {report['impact_time']:.4f} s")
    click.echo(f"impact duration  {report['impact_duration'] * 1e3:.2f} ms")
    click.echo(f"impulse          {fixed(report['impulse'])} N s")
    click.echo(f"{'':<17}" + "".join(f"{f'dq{i}':>9}" for i in range(1, len(report["dq_jump"]) + 1)))
    click.echo(f"{'simulated jump':<17}" + "".join(f"{x:9.4f}" for x in report["dq_jump"]))
    for name, jump in report["predicted"].items():
        click.echo(f"{name:<17}" + "".join(f"{x:9.4f}" for x in jump))
    click.echo(
        f"max |dq|/dq_max over 50 ms: {report['max_velocity_ratio']:.3f}   "
        f"max impulsive torque ratio: {report['max_torque_ratio']:.3f}   "
        f"violated: {report['violated']}"
    )
    if out_dir is not None:
        click.echo(f"trial {spec.trial_id} written to {out_dir}")


def rows_friction(friction: float) -> float:
    """The mu of --friction, in the friction rows' range (``FrictionRows``)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.friction_pyramid import FrictionRows

    try:
        return FrictionRows(friction).friction
    except BadInputError as error:
        raise BadInputError(f"--friction: {error}") from None


def frictional_wall(surface: Surface, friction: float, plant, no_rows: bool, jump_model: str) -> Surface:
    """``surface`` with the friction of ``--friction`` (the rows' mu, ``FrictionRows``' range),
    checked against the other options: a plant file that sets the wall's friction too, or a
    model without friction rows (classical_normal; none with --no-jump-constraint), is bad input."""
    mu = rows_friction(friction)
    if plant is not None and plant.friction is not None:
        raise BadInputError("--friction and the plant's 'friction' both set the wall's friction; give one")
    if no_rows:
        raise BadInputError("--friction sets the jump constraints' friction rows; they are off with --no-jump-constraint")
    if jump_model == "classical_normal" and mu > 0.0:
        raise BadInputError("--friction: the classical_normal model has no friction rows; choose another --jump-model")
    return Surface(surface.point, surface.normal, mu)


def stance_trial(
    choice: RobotChoice, posture: str, speed: float, files: dict, controller: str = "scripted",
    friction: float | None = None,
) -> tuple[dict, str | None]:
    """One trial of the floating-base robot of ``choice`` (``scenarios.trial.TrialRunner``, the
    standing trial of ``sim.runner.run_impact_trial``) driven by the
    scripted command or (``controller="qp"``) the whole-body QP with the ``--jump-model``
    predictor (crb, gm or classical) and, with ``friction`` (--friction), its robust friction rows
    of that mu on a wall of that mu (``sim.runner.standing_wall_friction``), optionally rendered
    to a GIF (``files["video_file"]``) and added to the G1 dataset in ``files["out_dir"]``; its
    JSON (with the QP: ``controller``, ``cycles_not_ok`` and ``friction`` added) and the id of
    the trial written (None without ``out_dir``)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
    from impactqp.scenarios.campaign import posture_of
    from impactqp.scenarios.trial import TrialRunner
    from impactqp.scenarios.impact_figure import ImpactLabel
    from impactqp.sim.generation import open_dataset, write_trials
    from impactqp.sim.runner import TrialSpec
    from impactqp.sim.trial_sources import SCRIPTED, QpCommand

    reject_options(["tangential_text", "no_jump_constraint", "plant_file", "wall_point", "wall_normal",
                    "tool"] + (["jump_model"] if controller == "scripted" else []))
    out_dir = files["out_dir"]
    check_pictures(files)
    source = SCRIPTED
    if controller == "qp":
        method = click.get_current_context().params["jump_model"]
        if method not in METHODS:
            raise BadInputError(f"--jump-model {method} is not a floating-base predictor; choose from {', '.join(METHODS)}")
        source = QpCommand(method=method, friction=None if friction is None else rows_friction(friction))
    elif friction is not None:
        raise BadInputError("--friction sets the whole-body QP's friction rows: give --controller qp")
    stance = stance_names(choice.robot, posture)[0]
    simulated_speed(speed, "--speed")
    dataset = None if out_dir is None else open_dataset(output_directory(out_dir, "--out"), choice.robot)
    runner = TrialRunner.build(DEFAULT_WALL, None, choice, source)
    trial = runner.run(TrialSpec(stance, posture_of(choice, stance), speed))
    written = None if dataset is None else write_trials(dataset, [trial])[0].id
    write_pictures(runner, trial, files, ImpactLabel(choice.robot, "its hand", stance))
    report = trial.to_json(choice.robot.name)
    if controller == "qp":
        report.update(controller="qp", jump_model=source.method, cycles_not_ok=trial.record.not_ok,
                      friction=source.friction)
    return report, written


def check_pictures(files: dict) -> None:
    """Refuse, before anything is simulated, a --video, --figure or --view that cannot be made:
    a file name of another format or in no writable directory, no offscreen renderer, no
    display for the viewer."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.impact_figure import check_figure_suffix
    from impactqp.scenarios.video import viewer_problem

    if files["video_file"] is not None:
        video_output(files["video_file"])
    if files["figure_file"] is not None:
        check_figure_suffix(output_file(files["figure_file"], "--figure"))
    if files["view"]:
        problem = viewer_problem()
        if problem is not None:
            raise BadInputError(f"--view: {problem}")


def write_pictures(runner, trial, files: dict, label) -> None:
    """The --video, --figure and --view of ``trial`` (``scenarios.video``,
    ``scenarios.impact_figure``), each when asked."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.impact_figure import write_velocity_figure
    from impactqp.scenarios.video import view_trial, write_trial_video

    if files["video_file"] is not None:
        write_trial_video(runner, trial, files["video_file"])
    if files["figure_file"] is not None:
        write_velocity_figure(trial, label, files["figure_file"])
    if files["view"]:
        view_trial(runner, trial)


def stance_trial_text(report: dict) -> str:
    """A floating-base robot's trial report as text."""
    return "\n".join([
        f"{report['posture']} ({report['robot']}): commanded {report['reference_speed']} m/s, contact speed "
        f"{report['contact_speed']:.4f} m/s, impulse {np.round(report['impulse'], 4).tolist()} N s",
        "errors (26): " + ", ".join(f"{m} {e:.4f}" for m, e in report["errors"].items()),
        f"foot slip {1e3 * report['foot_slip']:.2f} mm, lift {1e3 * report['foot_lift']:.2f} mm, fell: {report['fell']}, "
        f"max |dq|/dq_max {report['max_velocity_ratio']:.3f}, failed first: {report['first_failure'] or '-'}",
    ] + ([f"whole-body QP ({report['jump_model']}): {report['cycles_not_ok']} cycles not OK"]
         if report.get("controller") == "qp" else []))


# ---------------------------------------------------------------------------- campaign
def campaign_speeds(speeds_text, tangential_text, floating: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The normal speeds (default: the paper's for an arm, the humanoid campaign's for a floating
    base) and the tangential series (an arm's; default the paper's, 'none' skips it) of the options."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.campaign import PAPER_SPEEDS, PAPER_TANGENTIAL_SPEEDS, STANCE_SPEEDS

    default = STANCE_SPEEDS if floating else PAPER_SPEEDS
    speeds = default if speeds_text is None else tuple(parse_list(speeds_text, "--speeds"))
    for v in speeds:
        simulated_speed(v, "every speed of --speeds")
    if floating or (tangential_text is not None and tangential_text.strip().lower() == "none"):
        return speeds, ()
    if tangential_text is None:
        return speeds, PAPER_TANGENTIAL_SPEEDS
    return speeds, tuple(parse_list(tangential_text, "--tangential"))


@click.command()
@click.option("--postures", "postures_text", help="Comma-separated posture names; default: all.")
@click.option("--speeds", "speeds_text", help="Comma-separated normal speeds (m/s); default 0.08,0.10,0.12,0.15,0.18.")
@click.option(
    "--tangential", "tangential_text",
    help="Tangential speeds (m/s) of the series at v_n = 0.12 on the first posture; default 0.03..0.12; 'none' skips it.",
)
@plant_option
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--out", "out_dir", default="out/campaign", show_default=True, help="Output directory.")
@click.option("--json", "as_json", is_flag=True, help="Print Table I as JSON (no progress bar).")
@max_trials_option
@robot_options(humanoid=True)
def campaign(postures_text, speeds_text, tangential_text, plant_file, out_dir, as_json, choice, **work):
    """The paper's campaign in simulation: dataset, Table I (table1.json, table1.md) and figures
    in --out (with --robot g1: stances x speeds of the standing G1, its dataset and Table I, no
    figures)."""
    jobs, max_trials = work["jobs"], work["max_trials"]
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.campaign import Campaign, CampaignPlan, CampaignTrials, check_postures

    robot = choice.robot
    if robot.floating:
        reject_options(["tangential_text", "plant_file", "tool"])
    postures = check_postures(robot, None if postures_text is None else (s.strip() for s in postures_text.split(",")))
    speeds, tangential = campaign_speeds(speeds_text, tangential_text, robot.floating)
    plan = CampaignPlan(postures, speeds, tangential, max_trials=max_trials)
    trials = CampaignTrials(choice, DEFAULT_WALL, load_plant(plant_file))
    output_directory(out_dir, "--out")
    table = Campaign(plan, trials, jobs=check_jobs(jobs), progress=show_progress(as_json)).run(out_dir)
    if as_json:
        emit_json(table.to_json())
        return
    click.echo(table.text())
    *first, last = ["dataset", *table.files(), *(["figures"] if table.figures else [])]
    click.echo(f"{', '.join(first)} and {last} written to {out_dir}")
