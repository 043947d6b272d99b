"""``impactqp run``: the impact session in a 1 kHz robot loop (``scenarios.run``)."""

from __future__ import annotations

import click

from impactqp.scenarios.cli.arguments import EXIT_INTERRUPTED, emit_json, robot_options


@click.command("run")
@click.option("--backend", type=click.Choice(["sim", "franka", "replay"]), default="sim", show_default=True)
@click.option("--robot-ip", help="The robot's address (franka backend).")
@click.option("--config", "config_file", help="Controller configuration (.toml, .yaml); default: approach at --speed.")
@click.option("--plant", "plant_file", help="JSON plant-parameter overrides (sim backend).")
@click.option("--posture", default="elbow_up", show_default=True, help="Start posture (sim backend).")
@click.option("--speed", type=float, default=0.15, show_default=True, help="Approach speed (m/s) of the default configuration.")
@click.option("--duration", type=float, default=1.0, show_default=True, help="Control time (s) before braking to a stop.")
@click.option("--log", default="out/run", show_default=True, help="Dataset directory the run is added to.")
@click.option("--dataset", help="Dataset directory of the trial to replay (replay backend).")
@click.option("--trial", help="Trial id to replay (default: the first).")
@click.option("--unpaced", is_flag=True, help="Run the sim backend as fast as it goes (no wall-clock pacing).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@robot_options
def run_command(
    backend, robot_ip, config_file, plant_file, posture, speed, duration, log, dataset, trial, unpaced, as_json, choice
):
    """Run the impact-aware controller in a 1 kHz loop on a robot: approach, detect the impact,
    post-impact phase, brake to a stop. Ctrl-C (or SIGTERM) brakes to a stop, keeps the log and
    exits with code 130."""
    from impactqp.scenarios.run import RunRequest, run  # lazy: the command line loads an experiment when it runs

    request = RunRequest(
        backend=backend, robot_ip=robot_ip, config_file=config_file, plant_file=plant_file, posture=posture,
        speed=speed, duration=duration, log=log, dataset=dataset, trial=trial, unpaced=unpaced, choice=choice,
    )
    report, result = run(request)
    if as_json:
        emit_json(report)
    else:
        print_report(report)
    if result.interrupted:
        click.echo(f"impactqp: interrupted: braked to a stop; log: {report['log']}", err=True)
        click.get_current_context().exit(EXIT_INTERRUPTED)


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
    click.echo(f"final phase: {report['phase']}; log: {report['log']}")
