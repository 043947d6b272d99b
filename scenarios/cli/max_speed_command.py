"""``impactqp max-speed``: the highest feasible contact speed of a posture, one path for every
robot (docs/max-speed.md, docs/floating-base.md).

The options are checked, the search runs and its JSON report is printed, or the text made from
that report. What differs between robots is data, read where it must be: a robot with a floating
base (its description's ``base``) is searched per stance of its description
(``scenarios.max_speed_search.search_stance``: closed form and simulated bisection, the trials
driven by its scripted arm or, ``--controller qp``, by the whole-body QP; an option of the arm's
search that has no meaning there is bad input when given), a fixed-base arm
per named posture on a wall (``scenarios.max_speed_search.MaxSpeedSearch``: closed form,
QP-limited run and simulated bisection). With ``--friction`` the answer is the closed form under
the robust friction rows (``controller.model.friction_max_speed.frictional_max_speed``: every
predictor at the posture or stance, sliding at ``--tangential``), without simulation; a standing
robot's ``--controller qp --friction`` instead runs its simulated search with the QP's friction rows,
its checks asked at factors of crb's closed form under those rows.
Bad input ends with one line on stderr and exit code 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import click
import numpy as np

from impactqp.controller.model.choice import RobotChoice
from impactqp.controller.model.max_speed import DEFAULT_IMPACT_DURATION, HAND_IMPACT_DURATION, Setting
from impactqp.controller.model.validation import BadInputError, positive
from impactqp.controller.model.validation import impact_duration as check_impact_duration
from impactqp.controller.model.validation import restitution as restitution_coefficient
from impactqp.scenarios.cli.arguments import (
    check_jobs,
    emit_json,
    load_plant,
    output_file,
    reject_options,
    robot_options,
    stance_names,
)
from impactqp.scenarios.cli.stderr_log import show_progress
from impactqp.scenarios.cli.simulation_commands import (
    check_reachable,
    plant_option,
    rows_friction,
    wall,
    wall_normal_option,
    wall_point_option,
)


@dataclass(frozen=True)
class MaxSpeedRequest:
    """The options of ``max-speed``, as given on the command line (``choice``: --robot, --tool)."""

    posture: str
    jump_model: str
    restitution: float
    impact_duration: float
    plant: str | None
    wall_point: str | None
    wall_normal: str | None
    jobs: int
    tolerance: float
    choice: RobotChoice
    friction: float | None = None
    tangential: str | None = None
    controller: str = "scripted"
    feedback: str | None = None
    governor: str = "1.0"


def arm_max_speed(request: MaxSpeedRequest, progress: bool) -> dict:
    """The JSON report of a fixed-base arm's search at a named posture on the wall."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.max_speed_search import QP_START_DISTANCE, MaxSpeedSearch, QpSetting

    choice, restitution, impact_duration, tolerance = request.choice, request.restitution, request.impact_duration, request.tolerance
    posture = choice.posture(request.posture)
    restitution_coefficient(restitution, "--restitution")
    check_impact_duration(impact_duration, "--impact-duration")
    positive(tolerance, "--tolerance")
    surface = wall(request.wall_point, request.wall_normal)
    plant = load_plant(request.plant)
    check_reachable(choice, posture, surface, QP_START_DISTANCE)
    search = MaxSpeedSearch(
        posture, surface, plant, setting=QpSetting(request.jump_model, restitution, impact_duration),
        tolerance=tolerance, jobs=check_jobs(request.jobs), progress=progress, choice=choice,
    )
    return search.run().to_json()


QP_CHECKS = (0.9, 1.3)
"""With ``--controller qp``, a trial asked for each of these factors of the crb closed form."""


def stance_max_speed(request: MaxSpeedRequest) -> dict:
    """The JSON report of a floating-base robot's search at a stance of its description: its
    ``robot``, the closed form of each predictor and ``robust`` (the smallest), the bisection of
    the trials driven by ``controller`` (the scripted arm, or the whole-body QP with one trial
    asked for each of :data:`QP_CHECKS` times the closed form ``checks_reference``,
    :func:`checks_reference`), and the contact duration used (the description's wall contact unless
    --impact-duration); the bisection's tolerance is ``max_speed_search.STANCE_TOLERANCE`` on the
    commanded speed unless --tolerance. With --friction (with --controller qp; without it the closed
    form with friction, :func:`frictional_max_speed_report`), the QP's robust friction rows of that mu
    on a wall of that mu in every trial (``trials_friction``), and the checks' reference is crb's
    closed form under those rows; the per-predictor closed form beside them stays frictionless.
    Several stances (comma-separated): one such report per stance under ``stances``."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS as METHODS
    from impactqp.controller.model.robot import RobotModel
    from impactqp.scenarios.max_speed_search import STANCE_TOLERANCE, SpeedChecks, search_stance
    from impactqp.sim.trial_sources import SCRIPTED, QpCommand

    reject_options(["jump_model", "plant_file", "wall_point", "wall_normal", "jobs", "tool", "tangential"])
    robot = request.choice.robot
    stances = stance_names(robot, request.posture)
    c_r = restitution_coefficient(request.restitution, "--restitution")
    duration = check_impact_duration(request.impact_duration, "--impact-duration") if given("impact_duration") else HAND_IMPACT_DURATION
    tolerance = request.tolerance if given("tolerance") else STANCE_TOLERANCE
    qp = request.controller == "qp"
    if not qp and request.feedback is not None:
        raise BadInputError("--feedback chooses the state the whole-body QP is given: give --controller qp")
    if not qp and given("governor"):
        raise BadInputError("--governor caps the whole-body QP's speed target: give --controller qp")
    governor = governor_share(request.governor)
    friction = None if request.friction is None else rows_friction(request.friction)
    model = RobotModel(robot)
    reports = []
    setting = Setting("crb", c_r, impact_duration=duration)
    for stance in stances:
        reference = checks_reference(model, stance, setting, friction) if qp and friction is not None else None
        checks = SpeedChecks(QP_CHECKS, None if reference is None else reference["speed"]) if qp else SpeedChecks()
        result = search_stance(model, stance, setting, tolerance=tolerance,
                               source=QpCommand(feedback=request.feedback, friction=friction, governor=governor) if qp else SCRIPTED,
                               checks=checks)
        report = {"robot": robot.name, "controller": request.controller, **result.to_json()}
        if request.friction is not None:
            report["trials_friction"] = friction
        if qp:
            report["checks_reference"] = reference or {
                "closed_form": "frictionless", "method": "crb", "speed": report["predicted_max_speed"]["crb"],
                **report["binding"]["crb"],
            }
        speeds = report["predicted_max_speed"]
        robust = min(METHODS, key=lambda m: math.inf if speeds[m] is None else speeds[m])
        speeds["robust"], report["binding"]["robust"] = speeds[robust], report["binding"][robust]
        report["impact_duration"] = duration
        reports.append(report)
    return reports[0] if len(reports) == 1 else {"robot": robot.name, "controller": request.controller, "stances": reports}


def governor_share(text: str) -> float | None:
    """--governor: "off" (None), or the share (> 0) of the closed form at the contact posture that
    caps the QP's speed target (``sim.trial_sources.QpCommand.governed_speed``)."""
    if text == "off":
        return None
    try:
        share = float(text)
    except ValueError:
        share = math.nan
    if not (share > 0.0 and math.isfinite(share)):
        raise BadInputError(f"--governor must be 'off' or a share > 0 of the closed form, got {text!r}")
    return share


def checks_reference(model, stance: str, setting: Setting, friction: float) -> dict:
    """The closed form that a standing robot's QP-driven checks are factors of, with friction rows of
    mu = ``friction`` in its trials: crb's under the robust friction rows of that mu at the stance,
    the hand approaching along the wall's normal with no slide (one call of
    ``friction_max_speed.frictional_max_speed``), its speed (None when unbounded), what binds it and
    the block."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.friction_max_speed import frictional_max_speed
    from impactqp.controller.model.friction_pyramid import FrictionRows
    from impactqp.controller.model.humanoid_stance import stance_posture
    from impactqp.sim.runner import NORMAL

    q = stance_posture(model, model.description.stances[stance])
    answer = frictional_max_speed(model, model.terms(q), NORMAL, np.zeros(3), setting, FrictionRows(friction))
    speed = answer.max_speed
    return {"closed_form": "frictional", "method": setting.method, "friction": friction, "speed": finite(speed.speed),
            "criterion": speed.criterion, "where": speed.where, "block": answer.block}


def given(option: str) -> bool:
    """Whether the command line gave ``option`` (a parameter's name), rather than its default."""
    return click.get_current_context().get_parameter_source(option) != click.core.ParameterSource.DEFAULT


FRICTION_METHODS = ("crb", "gm", "classical")
"""The predictors of the closed form under the robust friction rows (``--friction``)."""


def frictional_max_speed_report(request: MaxSpeedRequest) -> dict:
    """The JSON report of the closed form under the robust friction rows (``--friction``, 4-edge
    pyramid), no simulation: an arm's at a named posture on its wall, a floating-base robot's at
    each stance (comma-separated; the wall ahead, normal -x, T the wall contact's unless
    --impact-duration), sliding at ``--tangential`` (:func:`frictional_posture_report`)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.friction_pyramid import FrictionRows
    from impactqp.controller.model.humanoid_stance import stance_posture
    from impactqp.controller.model.validation import tangential_velocity
    from impactqp.scenarios.cli.arguments import parse_vector
    from impactqp.sim.runner import NORMAL

    try:
        rows = FrictionRows(request.friction)
    except BadInputError as error:
        raise BadInputError(f"--friction: {error}") from None
    robot = request.choice.robot
    closed_form = "--friction (the closed form under the friction rows, no simulation; docs/frictional-impacts.md)"
    if robot.floating:
        reject_options(["jump_model", "plant_file", "wall_point", "wall_normal", "jobs", "tolerance", "tool"], closed_form)
        duration = check_impact_duration(request.impact_duration, "--impact-duration") if given("impact_duration") else HAND_IMPACT_DURATION
        normal = NORMAL
    else:
        reject_options(["jump_model", "plant_file", "wall_point", "jobs", "tolerance"], closed_form)
        duration = check_impact_duration(request.impact_duration, "--impact-duration")
        normal = wall(None, request.wall_normal).normal
    c_r = restitution_coefficient(request.restitution, "--restitution")
    tangential = np.zeros(3) if request.tangential is None else tangential_velocity(
        parse_vector(request.tangential, 3, "--tangential"), normal, "--tangential")
    model = request.choice.shared_model
    if robot.floating:
        postures = [(name, stance_posture(model, robot.stances[name])) for name in stance_names(robot, request.posture)]
    else:
        posture = request.choice.posture(request.posture)
        postures = [(posture.name, posture.q)]
    reports = [
        {"posture": name, "robot": robot.name, "friction": rows.friction, "pyramid_edges": rows.edges,
         "tangential": tangential.tolist(), "normal": normal.tolist(), "restitution": c_r, "impact_duration": duration,
         **frictional_posture_report(model, model.terms(q), (normal, tangential), Setting(restitution=c_r, impact_duration=duration), rows)}
        for name, q in postures
    ]
    return reports[0] if len(reports) == 1 else {"robot": robot.name, "friction": rows.friction, "stances": reports}


def frictional_posture_report(model, terms, motion: tuple, setting: Setting, rows) -> dict:
    """Per predictor of :data:`FRICTION_METHODS` and ``robust`` (the smallest) the closed form under
    ``rows`` at the posture of ``terms`` for the contact motion (normal, tangential velocity)
    (``friction_max_speed.frictional_max_speed``): the speed, what binds it (criterion, where, joint,
    block) and the frictional impact's mode, beside the frictionless closed form (mu = 0)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.friction_pyramid import FrictionRows
    from impactqp.controller.model.friction_max_speed import frictional_max_speed

    normal, tangential = motion
    answers = {}
    for method in FRICTION_METHODS:
        own = replace(setting, method=method)
        answers[method] = (
            frictional_max_speed(model, terms, normal, tangential, own, rows),
            frictional_max_speed(model, terms, normal, tangential, own, FrictionRows()),
        )
    answers["robust"] = min(answers.values(), key=lambda pair: pair[0].max_speed.speed)
    return {
        "predicted_max_speed": {m: finite(a.max_speed.speed) for m, (a, _) in answers.items()},
        "frictionless_max_speed": {m: finite(b.max_speed.speed) for m, (_, b) in answers.items()},
        "binding": {
            m: {"criterion": a.max_speed.criterion, "where": a.max_speed.where, "joint": a.max_speed.joint,
                "block": a.block, "mode": a.mode, "mu_bar": finite(a.mu_bar)}
            for m, (a, _) in answers.items()
        },
    }


def finite(x: float) -> float | None:
    """A JSON number: None for inf and nan."""
    return float(x) if math.isfinite(x) else None


def run_max_speed(request: MaxSpeedRequest, progress: bool) -> dict:
    """Check the ``max-speed`` options and run the search of the chosen robot: its JSON report."""
    if request.tangential is not None and request.friction is None:
        raise BadInputError("--tangential is the sliding of the closed form with --friction; give --friction too")
    if request.choice.robot.floating:
        if request.friction is not None and request.controller != "qp":
            return frictional_max_speed_report(request)
        return stance_max_speed(request)
    if request.controller != "scripted":
        raise BadInputError("--controller chooses a standing robot's command source; an arm's search runs its QP always")
    if request.feedback is not None:
        raise BadInputError("--feedback chooses the state a standing robot's QP is given (with --controller qp)")
    if given("governor"):
        raise BadInputError("--governor caps a standing robot's QP speed target (with --controller qp)")
    if request.friction is not None:
        return frictional_max_speed_report(request)
    return arm_max_speed(request, progress)


def max_speed_text(report: dict) -> str:
    """A ``max-speed`` JSON report as text: the closed form of each predictor and what binds it
    (a joint, or where the criterion binds), then the QP-limited run and every simulated impact
    when the report has them (an arm's), or the bisection's contact speed and first failure."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.max_speed_search import binding_text

    robot = f" ({report['robot']})" if "robot" in report else ""
    if "stances" in report:
        return "\n\n".join(max_speed_text(stance) for stance in report["stances"])
    if "friction" in report:
        return frictional_text(report)
    constraints = f", jump constraints {report['jump_model']}" if "jump_model" in report else ""
    lines = [
        f"{report['posture']}{robot}: highest feasible contact speed (m/s){constraints}",
        f"{'closed form':<14}{'speed':>8}  binds",
    ]
    for name, speed in report["predicted_max_speed"].items():
        lines.append(f"  {name:<12}{speed if speed is not None else math.inf:8.4f}  {binding_text(report['binding'][name])}")
    if "qp_limited_speed" not in report:
        driver = " by the QP" if report.get("controller") == "qp" else ""  # reports of the scripted arm may lack the key
        if "trials_friction" in report:
            driver += f" with friction rows, mu = {report['trials_friction']:g}"
        if "checks_reference" in report:
            lines.append(reference_text(report["checks_reference"]))
        lines.append(f"{'simulated':<14}{report['simulated_max_speed']:8.4f}  commanded{driver}; contact "
                     f"{report['simulated_contact_speed']:.4f}; failed first above: {report['simulated_failed_first'] or '-'}")
        lines.extend(check_text(factor, e) for factor, e in report.get("checks", {}).items())
        return "\n".join(lines)
    lines.append(
        f"{'QP-limited':<14}{report['qp_limited_speed']:8.4f}  (asked 2 m/s; observed |dq|/dq_max "
        f"{report['qp_max_velocity_ratio']:.3f}, impulsive torque ratio {report['qp_max_torque_ratio']:.3f})"
    )
    lines.append(
        f"{'simulated':<14}{report['simulated_max_speed']:8.4f}  (jump constraints off, "
        f"{len(report['evaluations'])} simulated impacts)"
    )
    lines.append(f"  {'reference':>10}{'contact':>10}{'|dq| ratio':>12}{'torque ratio':>14}  violated")
    for e in report["evaluations"]:
        lines.append(
            f"  {e['reference_speed']:10.4f}{e['contact_speed']:10.4f}{e['max_velocity_ratio']:12.3f}"
            f"{e['max_torque_ratio']:14.3f}  {e['violated']}"
        )
    return "\n".join(lines)


def reference_text(reference: dict) -> str:
    """The closed form a report's checks are factors of: which one (frictional: mu), its speed and
    what binds it."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.max_speed_search import binding_text

    name = f"{reference['method']}, mu {reference['friction']:g}" if reference["closed_form"] == "frictional" else reference["method"]
    block = f", {reference['block']}" if reference.get("block") else ""
    speed = reference["speed"] if reference["speed"] is not None else math.inf
    return (f"  {name:<12}{speed:8.4f}  {binding_text(reference)}{block}: "
            f"the checks' reference, the {reference['closed_form']} closed form")


def check_text(factor: str, e: dict) -> str:
    """One trial asked for ``factor`` times the checks' reference (crb's closed form, frictional with
    --friction: :func:`reference_text`): asked and contact speed, the binding impact rows, the
    failed criteria's onsets (ms from the contact), whether it fell and the QP's cycles not OK
    (the asked speed followed by the QP's target when its governor capped it)."""
    onsets = ", ".join(f"{name} {1000 * t:+.0f} ms" for name, t in e["onsets"].items()) or "none"
    target = e["speed_target"]
    governed = f" (target {target:.4f})" if target is not None and target < e["reference_speed"] else ""
    return (f"  {factor}x crb: asked {e['reference_speed']:.4f}{governed}, contact {e['contact_speed']:.4f}; "
            f"binding: {e['binding'] or '-'}; onsets: {onsets}; fell: {'yes' if e['fell'] else 'no'}; "
            f"cycles not OK: {e['not_ok']}")


def frictional_text(report: dict) -> str:
    """A ``max-speed --friction`` report as text."""
    lines = [
        f"{report['posture']} ({report['robot']}): highest normal contact speed (m/s) under the robust friction rows, "
        f"mu = {report['friction']}, {report['pyramid_edges']} edges, sliding at {report['tangential']} m/s",
        f"{'closed form':<14}{'speed':>8}{'no friction':>13}  binds",
    ]
    for name, speed in report["predicted_max_speed"].items():
        b, without = report["binding"][name], report["frictionless_max_speed"][name]
        lines.append(
            f"  {name:<12}{speed if speed is not None else math.inf:8.4f}{without if without is not None else math.inf:13.4f}  "
            f"{b['criterion']} ({b['where']}), {b['block'] or '-'}; contact {b['mode'] or '-'}"
        )
    return "\n".join(lines)


@click.command("max-speed")
@click.option("--posture", "posture_name", required=True, help="A named posture (see `impactqp postures`).")
@click.option(
    "--jump-model", type=click.Choice(["crb", "gm", "classical", "robust"]), default="crb", show_default=True,
    help="Model of the jump-aware constraints in the QP-limited run.",
)
@click.option("--restitution", type=float, default=0.0, show_default=True, help="c_r in [0, 1].")
@click.option("--impact-duration", type=float, default=DEFAULT_IMPACT_DURATION, show_default=True, help="delta_t (s).")
@plant_option
@wall_point_option
@wall_normal_option
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--tolerance", type=float, default=0.005, show_default=True,
              help="Bisection tolerance (m/s; a standing robot's: 0.02 on the commanded speed unless given).")
@click.option("--friction", type=float,
              help="mu in [0, 2]: the closed form under the robust friction rows (no simulation; a standing robot's "
                   "--controller qp: its trials with the QP's friction rows).")
@click.option("--tangential", help="With --friction: the tangential velocity VX,VY,VZ (m/s) of the sliding approach.")
@click.option(
    "--controller", type=click.Choice(["scripted", "qp"]), default="scripted", show_default=True,
    help="A standing robot's trials: its scripted arm, or the whole-body QP (with trials at 0.9x and 1.3x the closed form).",
)
@click.option(
    "--feedback", type=click.Choice(["commanded", "blended", "measured"]),
    help="With --controller qp: the state the QP is given (its own command, a blend with the measurement, the measurement; "
         "default: blended).",
)
@click.option(
    "--governor", default="1.0", show_default=True,
    help="With --controller qp: the hand's speed target capped at this share of the closed form at the stance ('off': the asked speed).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON (no progress bar).")
@click.option("--figure", "figure_file", help="Plot the speed of each predictor and simulation, what binds it (.png, .pdf, .svg).")
@robot_options(humanoid=True)
def max_speed(posture_name, plant_file, as_json, figure_file, choice, **search):
    """Highest feasible contact speed: closed form, reached by the QP, and simulated (with
    --robot g1: closed form and simulated bisection of one or more stances, the trials driven by
    the scripted arm or, with --controller qp, the whole-body QP)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.impact_figure import check_figure_suffix
    from impactqp.scenarios.max_speed_figure import write_max_speed_figure

    if figure_file is not None:
        check_figure_suffix(output_file(figure_file, "--figure"))
        if choice.robot.floating and "," in posture_name:
            raise BadInputError("--figure draws one stance; give one --posture")
    report = run_max_speed(MaxSpeedRequest(posture=posture_name, plant=plant_file, choice=choice, **search),
                           show_progress(as_json))
    if figure_file is not None:
        tool = choice.tool.name if choice.tool is not None else "its hand"
        write_max_speed_figure(report, f"{choice.robot.name} with {tool}", figure_file)
    if as_json:
        emit_json(report)
        return
    click.echo(max_speed_text(report))
