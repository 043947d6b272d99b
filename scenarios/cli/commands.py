"""The ``impactqp`` commands: the click group and the small commands (``postures``, ``predict``,
``bench``, ``demo``); the others live beside it. ``predict --robot g1`` (a floating base,
docs/floating-base.md) predicts at a stance of its description, its feet held
(:func:`stance_prediction`). They parse options and call the library,
nothing more; the error boundary and the exit codes are ``scenarios.cli.main``'s.
"""

from __future__ import annotations

import logging

import click
import numpy as np

from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.cli.arguments import (
    emit_json,
    output_directory,
    parse_vector,
    reject_options,
    robot_options,
    stance_names,
)
from impactqp.scenarios.cli.stderr_log import log_to_stderr, show_progress


@click.group()
@click.version_option(package_name="impactqp", prog_name="impactqp")
@click.option("--debug", is_flag=True, help="Show the traceback of an internal error.")
@click.option("--verbose", is_flag=True, help="Also debug messages on stderr.")
@click.option("--quiet", is_flag=True, help="Only warnings and errors on stderr: no notes, no progress.")
@click.pass_context
def cli(ctx, debug, verbose, quiet):  # noqa: ARG001 - debug: read by main(), which owns the error boundary
    """Impact-aware QP control of a Franka Panda (Wang, Dehio, Kheddar, RA-L 2022).

    Results go to stdout; notes, progress, warnings to stderr (docs/cli.md)."""
    if verbose and quiet:
        raise click.UsageError("give at most one of --verbose and --quiet")
    ctx.call_on_close(log_to_stderr(logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO))


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list.")
@robot_options
def postures(as_json, choice):
    """List the robot's named impact postures (solved for the tool), their contact point and the
    wall normal."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.readable import fixed

    robot = choice.model()
    rows = [
        {
            "name": p.name,
            "q": p.q.tolist(),
            "contact_point": robot.contact_point(p.q).tolist(),
            "normal": p.surface.normal.tolist(),
            "description": p.description,
        }
        for p in choice.postures.values()
    ]
    if as_json:
        emit_json(rows)
        return
    for row in rows:
        click.echo(f"{row['name']:<12} {row['description']}")
        click.echo(f"  q             = {fixed(row['q'])} rad")
        click.echo(f"  contact point = {fixed(row['contact_point'])} m")
        click.echo(f"  normal        = {fixed(row['normal'])}")


@cli.command()
@click.option("--posture", "posture_name", help="A named posture (see `impactqp postures`).")
@click.option("--q", "q_text", help="Joint positions Q1,...,Q7 (rad).")
@click.option("--normal", "normal_text", required=True, help="Surface normal NX,NY,NZ towards the robot.")
@click.option("--speed", type=float, required=True, help="Approach speed along -normal (m/s), > 0.")
@click.option("--tangential", "tangential_text", help="Tangential velocity VX,VY,VZ (m/s), orthogonal to the normal.")
@click.option("--restitution", type=float, default=0.0, show_default=True, help="Coefficient of restitution in [0, 1].")
@click.option("--method", type=click.Choice([*METHODS, "all"]), default="all", show_default=True)
@click.option("--friction", type=float, help="Coulomb coefficient of the contact: a 3-D frictional impact (slip, stick).")
@click.option("--restitution-model", type=click.Choice(["energetic", "kinematic"]), default="energetic",
              show_default=True, help="With --friction: Stronge's energetic or Newton's kinematic restitution.")
@click.option("--json", "as_json", is_flag=True)
@robot_options(humanoid=True)
def predict(method, as_json, choice, **impact):
    """Predict the impact-induced joint-velocity jump at a posture of the robot with the tool
    (with --robot g1: a stance of the standing G1, --q of its nq values); with --friction, the
    3-D frictional impulse, the contact's mode (slip, stick, reversal) and the stick coefficient."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.prediction import ImpactQuery, predict_all
    from impactqp.scenarios.readable import fixed

    methods = METHODS if method == "all" else (method,)
    friction = {"friction": impact.pop("friction"), "restitution_model": impact.pop("restitution_model")}
    if choice.robot.floating:
        report = stance_prediction(choice, impact.pop("posture_name"), impact.pop("q_text"), impact | friction,
                                   None if method == "all" else methods)
        if as_json:
            emit_json(report)
            return
        click.echo(f"contact point = {fixed(report['contact_point'])} m, normal = {fixed(report['normal'])}")
        for name, res in report["methods"].items():
            mode = f"   {res['mode']}, mu_bar {res['mu_bar']:.4f}" if "mode" in res else ""
            click.echo(f"{name:<10} impulse {fixed(res['impulse'])} N s   CoM jump {fixed(res['com_jump'])} m/s{mode}")
        return

    if (impact["posture_name"] is None) == (impact["q_text"] is None):
        raise BadInputError("give exactly one of --posture NAME or --q Q1,...,Q7")
    if impact["posture_name"] is not None:
        q = choice.posture(impact["posture_name"]).q
    else:
        q = parse_vector(impact["q_text"], len(choice.robot.joints), "--q")
    tangential = parse_vector(impact["tangential_text"], 3, "--tangential") if impact["tangential_text"] else np.zeros(3)
    query = ImpactQuery.from_speed(
        q, parse_vector(impact["normal_text"], 3, "--normal"), impact["speed"], tangential, impact["restitution"],
        **friction,
    )
    report = predict_all(query, methods, choice.model())
    if as_json:
        emit_json(report)
        return
    click.echo(f"q                   = {fixed(report['q'])} rad")
    click.echo(f"contact point       = {fixed(report['contact_point'])} m")
    click.echo(f"normal              = {fixed(report['normal'])}")
    click.echo(f"pre-impact velocity = {fixed(report['pre_impact_velocity'])} m/s")
    click.echo(f"restitution         = {report['restitution']}   cond(M) = {report['cond_M']:.0f}")
    joints = range(1, len(report["q"]) + 1)
    header = f"{'method':<17}" + "".join(f"{f'dq{i}':>9}" for i in joints) + "   impulse (N s)"
    click.echo(header)
    for name, res in report["methods"].items():
        dq = "".join(f"{x:9.4f}" for x in res["dq_jump"])
        imp = " ".join(f"{x:7.4f}" for x in res["impulse"])
        mode = f"   {res['mode']} (mu_bar {res['mu_bar']:.3f})" if "mode" in res else ""
        click.echo(f"{name:<17}{dq}   [{imp}]{mode}")


def stance_prediction(choice, posture: str | None, q_text: str | None, impact: dict, methods) -> dict:
    """The ``predict`` report of the floating-base robot of ``choice`` (feet held): per method
    (``methods``; None: classical, gm, crb) the jump dq_jump (nv: base twist, joints), impulse,
    CoM jump and feet wrenches (JSON: the arm's keys where they mean the same); with ``impact``'s
    ``friction`` the frictional impulse of the held-contact W, its mode and mu_bar."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as FLOATING_METHODS
    from impactqp.controller.model.prediction import ImpactQuery, frictional_entry, method_prediction
    from impactqp.controller.model.robot import RobotModel
    from impactqp.controller.model.humanoid_stance import stance_posture
    from impactqp.controller.model.validation import approach_speed, tangential_velocity, unit_normal
    from impactqp.controller.model.validation import restitution as restitution_coefficient

    reject_options(["tool"])
    robot = RobotModel(choice.robot)
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
    query = ImpactQuery.from_speed(q, normal, speed, tangential, c_r, impact["friction"], impact["restitution_model"])
    terms = robot.terms(q)
    report = {
        "robot": choice.robot.name, "q": terms.q.tolist(), "contact_point": terms.contact_point.tolist(),
        "normal": normal.tolist(),
        "pre_impact_velocity": query.pre_impact_velocity.tolist(), "restitution": c_r,
        "cond_M": float(np.linalg.cond(terms.M)), "methods": {},
    }
    if query.friction is not None:
        report["friction"], report["restitution_model"] = query.friction, query.restitution_model
    for method in FLOATING_METHODS if methods is None else methods:
        jump, frictional = method_prediction(method, terms, query)
        report["methods"][method] = {
            "dq_jump": jump.dq_jump.tolist(), "impulse": jump.impulse.tolist(), "com_jump": jump.com_jump.tolist(),
            "feet_impulse": jump.held_impulse.tolist(),
        } | frictional_entry(frictional)
    return report


@cli.command()
@click.option("--json", "as_json", is_flag=True, help='Print {"rows": [...]}.')
@click.option("--only", default="", help="Run only the rows whose name starts with this prefix.")
def bench(as_json, only):
    """Benchmark table: median and p99 of every tracked speed and accuracy figure."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.bench import run_benchmarks

    rows = run_benchmarks(only)
    if as_json:
        emit_json({"rows": rows})
        return
    width = max([len(row["name"]) for row in rows] + [38]) + 2
    click.echo(f"{'name':<{width}}{'unit':<16}{'median':>14}{'p99':>14}")
    for row in rows:
        if row["median"] is None:  # a row that could not be measured says why
            click.echo(f"{row['name']:<{width}}{row['unit']:<16}{'n/a':>14}{'n/a':>14}  {row.get('note', '')}")
            continue
        note = f"  {row['note']}" if row.get("note") else ""
        click.echo(f"{row['name']:<{width}}{row['unit']:<16}{row['median']:>14.4g}{row['p99']:>14.4g}{note}")


@cli.command()
@click.option("--out", "out_dir", default="out/demo", show_default=True, help="Output directory.")
@click.option("--jobs", type=int, default=2, show_default=True, help="Worker processes.")
def demo(out_dir, jobs):
    """The whole story in under 2 minutes: simulate, measure, diagnose, calibrate, decide.

    1. The nominal campaign (3 postures x 5 normal speeds + 4 tangential speeds) and its Table I.
    2. A "measured" dataset from a stiff plant: drives with reflected rotor inertia (1.2 kg m^2
       on joints 1-4, 0.3 on joints 5-7), 3 postures x 2 speeds, with encoder and torque noise.
    3. The diagnosis of that dataset: the cause, its gain and Table I on the measured data, on
       which the CRB predictor wins.
    4. The highest feasible contact speed of elbow_up with the calibrated plant, and which answer
       to trust.
    5. One impact in pictures: the video of a trial with the robot's meshes and its joint
       velocities around the impact with each predictor's dq+ (out/demo/impact).

    Progress bars (stderr) show the simulated trials of stages 1, 2 and 4, notes the steps of
    stage 3 (``impactqp --quiet demo``: neither).
    """
    # lazy: the command line loads what a command needs when it runs
    from tqdm import tqdm

    from impactqp.scenarios.campaign import Campaign, CampaignPlan, CampaignTrials
    from impactqp.scenarios.cli.arguments import bar_progress, check_jobs
    from impactqp.scenarios.diagnosis_report import (
        feasible_speeds,
        table_by_condition,
        trusted_speed_text,
        write_report,
    )
    from impactqp.controller.model.choice import DEFAULT_CHOICE
    from impactqp.sim.causes import per_group
    from impactqp.sim.diagnosis import diagnose
    from impactqp.sim.generation import DatasetRequest, generate_dataset
    from impactqp.sim.plant import PlantParameters

    out = output_directory(out_dir, "--out")
    jobs = check_jobs(jobs)
    plan = CampaignPlan(tangential_speeds=(0.03, 0.06, 0.09, 0.12))
    table = Campaign(plan, CampaignTrials(), jobs=jobs, progress=show_progress()).run(out / "nominal")
    click.echo("1. Nominal simulation, Table I:")
    click.echo(table.text())
    stiff = PlantParameters(armature=per_group((1.2, 0.3), len(DEFAULT_CHOICE.robot.joints)))
    with tqdm(desc="measured dataset", unit="trial", disable=None if show_progress() else True) as bar:
        generate_dataset(
            out / "measured",
            DatasetRequest(plant=stiff, postures=["elbow_up", "elbow_left", "elbow_right"], speeds=[0.1, 0.18], seed=1),
            jobs=jobs,
            progress=bar_progress(bar),
        )
    click.echo(f"\n2. 'Measured' dataset from a stiff plant (hidden armature 1.2 / 0.3 kg m^2): {out / 'measured'}")
    result = diagnose(out / "measured", jobs=jobs)
    summary = result.summary()
    click.echo("\n3. Diagnosis:")
    click.echo(summary["message"])
    click.echo(f"causes: {', '.join(summary['causes']) or 'none'}, held-out gain {100 * summary['gain']:.0f} %")
    click.echo("Table I on the measured data (average error (26), rad/s):")
    click.echo("\n".join(table_by_condition(result)))
    speeds = feasible_speeds(result, PlantParameters(), postures=["elbow_up"], jobs=jobs, progress=show_progress())
    path = write_report(result, out / "diagnosis", speeds)
    click.echo("\n4. Highest feasible contact speed with the calibrated plant:")
    for row in speeds:
        click.echo(row.sentence())
    click.echo(trusted_speed_text(result, speeds))
    click.echo(f"\nreport: {path}")
    click.echo("\n5. One impact in pictures (elbow_up at 0.1 m/s):")
    for line in demo_pictures(out / "impact"):
        click.echo(line)
    click.echo(
        "This was the Panda with the impact tip; every command takes --robot panda|fr3|ur5|FILE.toml (your own "
        "robot's description, docs/robots.md; predict, simulate, campaign, max-speed and run also g1) and --tool "
        "impact_tip|franka_hand|pad|FILE.json, e.g. `impactqp campaign --robot ur5 --postures elbow_down`."
    )


def demo_pictures(out) -> list[str]:
    """The demo's fifth stage: one trial of the Panda with the impact tip at elbow_up, 0.1 m/s,
    from rest 5 cm before the wall (``impactqp simulate``'s), its joint velocities around the
    impact (``scenarios.impact_figure``) and its video with the robot's meshes
    (``scenarios.video``; none without an offscreen renderer, said in one line) in ``out``; the
    lines that say what was written."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.choice import DEFAULT_CHOICE
    from impactqp.controller.model.postures import DEFAULT_WALL
    from impactqp.scenarios.cli.simulation_commands import SIMULATE_START_DISTANCE
    from impactqp.scenarios.impact_figure import ImpactLabel, write_velocity_figure
    from impactqp.scenarios.trial import TrialRunner
    from impactqp.scenarios.video import offscreen_backend_problem, write_trial_video
    from impactqp.sim.runner import TrialSpec

    out = output_directory(out, "--out")
    posture = DEFAULT_CHOICE.posture("elbow_up")
    runner = TrialRunner.build(DEFAULT_WALL, None, DEFAULT_CHOICE)
    spec = TrialSpec(posture.name, posture.q, 0.1, jump_model="crb", start_at_rest=True, start_distance=SIMULATE_START_DISTANCE)
    trial = runner.run(spec)
    label = ImpactLabel(DEFAULT_CHOICE.robot, DEFAULT_CHOICE.tool.name, posture.name)
    lines = [f"joint velocities around the impact: {write_velocity_figure(trial, label, out / 'velocities.png')}"]
    problem = offscreen_backend_problem()
    if problem is None:
        lines.append(f"video with the robot's meshes: {write_trial_video(runner, trial, out / 'impact.gif')}")
    else:
        lines.append(f"no video: {problem}")
    return lines


from impactqp.scenarios.cli.simulation_commands import campaign, simulate  # noqa: E402
from impactqp.scenarios.cli.max_speed_command import max_speed  # noqa: E402

cli.add_command(simulate)
cli.add_command(campaign)
cli.add_command(max_speed)

from impactqp.scenarios.cli.dataset_commands import dataset, diagnose  # noqa: E402

cli.add_command(dataset)
cli.add_command(diagnose)

from impactqp.scenarios.cli.run_command import run_command  # noqa: E402

cli.add_command(run_command)

from impactqp.scenarios.cli.sweep_command import sweep  # noqa: E402
from impactqp.scenarios.cli.oblique_command import oblique  # noqa: E402

cli.add_command(sweep)
cli.add_command(oblique)
