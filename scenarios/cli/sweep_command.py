"""``impactqp sweep``: a feasibility map over contact points and settings (docs/sweep.md)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.cli.arguments import check_jobs, emit_json, load_plant, output_directory, robot_options
from impactqp.scenarios.cli.stderr_log import show_progress


@click.command()
@click.argument("config_path", required=False, type=click.Path(path_type=Path))
@click.option("--backend", type=click.Choice(["local", "ray"]), default="local", show_default=True,
              help="local: a process pool; ray: the cluster at RAY_ADDRESS, else a local Ray.")
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--out", default="out/sweep", show_default=True, help="Output directory (Parquet chunks, sweep.json, figures).")
@click.option("--resume", is_flag=True, help="Skip the chunks already in --out (same config, --simulate, --plant).")
@click.option("--simulate", is_flag=True,
              help="Also search each cell's simulated highest feasible speed (the bisection of max-speed).")
@click.option("--plant", "plant_file", help="Plant for --simulate: a JSON file of overrides (sim.plant) or a built-in name (identified_panda).")
@click.option("--example", is_flag=True, help="Print a small runnable config and exit.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON summary instead of a progress bar.")
@robot_options
def sweep(config_path, example, as_json, choice, **run):
    """Highest feasible contact speed over a grid of contact points and settings (Parquet in --out)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.sweep.config import EXAMPLE, load_config

    if example:
        click.echo(EXAMPLE, nl=False)
        return
    if config_path is None:
        raise click.UsageError("give a CONFIG.toml (or --example)")
    from impactqp.scenarios.sweep.backends import run_sweep
    from impactqp.scenarios.sweep.cells import Simulation

    simulate, plant_file = run["simulate"], run["plant_file"]
    out = output_directory(run["out"], "--out")
    check_jobs(run["jobs"])
    config = replace(load_config(config_path), choice=choice)
    if plant_file is not None and not simulate:
        raise BadInputError("--plant sets the plant of the simulated cells: add --simulate")
    simulation = Simulation(load_plant(plant_file)) if simulate else None
    summary = run_sweep(
        config, out, jobs=run["jobs"], backend=run["backend"], resume=run["resume"], progress=show_progress(as_json),
        simulation=simulation,
    )
    if as_json:
        emit_json(summary.as_dict())
    else:
        click.echo(
            f"{summary.cells} cells ({summary.cells_reachable} reachable"
            + (f", {summary.cells_simulated} simulated" if simulate else "")
            + f") in {out}, "
            f"{summary.chunks_skipped} of {summary.chunks} chunks resumed"
        )
