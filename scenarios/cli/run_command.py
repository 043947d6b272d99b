"""``impactqp run``: the impact session in a 1 kHz robot loop (``scenarios.run``)."""

from __future__ import annotations

import logging

import click

from impactqp.scenarios.cli.arguments import emit_json, output_directory, robot_options
from impactqp.scenarios.cli.exit_codes import EXIT_INTERRUPTED, EXIT_ROBOT_WOULD_STOP


log = logging.getLogger(__name__)

NO_LOG = "none (the run measured fewer samples than a trial needs)"


@click.command("run")
@click.option(
    "--backend", type=click.Choice(["sim", "franka", "panda", "replay"]), default="sim", show_default=True,
    help="sim: MuJoCo; franka: an FR3 (pylibfranka); panda: a Panda (panda-python's libfranka 0.9); replay: a logged trial.",
)
@click.option("--robot-ip", help="The robot's address (franka and panda backends).")
@click.option(
    "--realtime", type=click.Choice(["enforce", "ignore"]), default="enforce", show_default=True,
    help="franka and panda backends: require a real-time kernel (enforce) or run without one and keep no cycle deadline (ignore: a simulator).",
)
@click.option("--config", "config_file", help="Controller configuration (.toml, .yaml); default: approach at --speed.")
@click.option("--plant", "plant_file", help="Plant (sim backend): a JSON file of overrides or a built-in name (identified_panda).")
@click.option("--posture", default=None, help="Start posture (sim backend); default: the robot's default posture (elbow_up on the Franka arms).")
@click.option("--speed", type=float, default=0.15, show_default=True, help="Approach speed (m/s) of the default configuration.")
@click.option("--duration", type=float, default=1.0, show_default=True, help="Control time (s) before braking to a stop.")
@click.option("--log", default="out/run", show_default=True, help="Dataset directory the run is added to.")
@click.option("--dataset", help="Dataset directory of the trial to replay (replay backend).")
@click.option("--trial", help="Trial id to replay (default: the first).")
@click.option("--unpaced", is_flag=True, help="Run the sim backend as fast as it goes (no wall-clock pacing).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@robot_options(humanoid=True)
def run_command(realtime: str, as_json: bool, choice, **options):
    """Run the impact-aware controller in a 1 kHz loop on a robot: approach, detect the impact,
    post-impact phase, brake to a stop. Ctrl-C (or SIGTERM) brakes to a stop, keeps the log and
    exits with code 130. Overruns are reported on stderr; exit code 3 when the watchdog tripped or
    the overruns would have stopped a real robot."""
    from impactqp.scenarios.run import RunRequest, run  # lazy: the command line loads an experiment when it runs

    output_directory(options["log"], "--log")  # an empty --log would log nothing, silently
    request = RunRequest(realtime=realtime == "enforce", choice=choice, **options)
    report, result = run(request, say=lambda line: click.echo(f"impactqp: {line}", err=True))
    if as_json:
        emit_json(report)
    else:
        print_report(report)
    if result.interrupted:
        log.warning("interrupted: braked to a stop; log: %s", report["log"] or NO_LOG)
        click.get_current_context().exit(EXIT_INTERRUPTED)
    cycle = report["cycle_us"]
    timing = (
        f"{report['overruns']} overrun(s) in {report['cycles']} cycles, cycle time p99 {cycle['p99']:.0f} us, "
        f"max {cycle['max']:.0f} us"
    )
    if result.robot_stop_reason:
        who = "stopped the robot" if options["backend"] in ("franka", "panda") else "would have stopped a real robot"
        log.error("the run %s: %s; %s", who, result.robot_stop_reason, timing)
        click.get_current_context().exit(EXIT_ROBOT_WOULD_STOP)
    if report["overruns"]:
        log.warning("%s; at most %d period(s) in a row without a command on time, within the budget of %d",
                    timing, report["missed_in_a_row"], result.max_overruns - 1)


def print_report(report: dict) -> None:
    impact = report["impact"]
    cycle = report["cycle_us"]
    click.echo(
        f"{report['cycles']} cycles, {report['overruns']} overruns, cycle time p50 {cycle['p50']:.0f} us, "
        f"p99 {cycle['p99']:.0f} us, max {cycle['max']:.0f} us"
    )
    click.echo(f"watchdog trips: {report['watchdog_trips']} {report['watchdog_reason']}".rstrip())
    if impact["detected"]:
        latency = impact["detection_latency_ms"]
        click.echo(
            f"impact detected at t = {impact['time']:.4f} s"
            + (f" ({latency:.1f} ms after the contact start)" if latency is not None else "")
            + f", contact speed {impact['contact_speed']:.3f} m/s"
        )
    else:
        click.echo("no impact detected")
    speed = report["speed"]
    if speed["capped_by"]:
        click.echo(
            f"asked {speed['asked']:.3f} m/s, hit at {speed['contact']:.3f} m/s: the controller capped the approach "
            f"(active: {', '.join(speed['capped_by'])}; docs/max-speed.md)"
        )
    elif speed["slower"]:
        click.echo(
            f"asked {speed['asked']:.3f} m/s, hit at {speed['contact']:.3f} m/s: no limit was active at the last "
            "approach command (the approach had not reached its speed, or its task traded it off)"
        )
    click.echo(f"final phase: {report['phase']}; log: {report['log'] or NO_LOG}")
    print_robot(report)


def print_robot(report: dict) -> None:
    """The robot backends' lines: the move to the start, the connection, a reflex."""
    move, robot = report.get("start_move"), report.get("robot")
    if move:
        via = f", through a retreat of {1e3 * move['retreat']:.0f} mm" if move["retreat"] else ""
        click.echo(
            f"moved to the start posture in {move['duration']:.2f} s ({move['cycles']} cycles{via}, the tool at least "
            f"{1e3 * move['clearance']:.0f} mm in front of the surface), final error {move['final_error']:.4f} rad"
        )
    if robot:
        click.echo(
            f"robot: command success rate {robot['command_success_rate']:.3f}, {robot['missed_packets']} missed packets, "
            f"mass matrix {100 * robot['model_difference']:.1f} % from our model"
        )
        if robot["reflex"]:
            recovered = "; error state cleared (automatic_error_recovery)" if robot["recovered"] else ""
            click.echo(f"robot reflex: {', '.join(robot['reflex'])}{recovered}")
