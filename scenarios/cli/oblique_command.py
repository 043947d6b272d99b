"""``impactqp oblique``: the frictional impact law against MuJoCo's simulated wall
(``scenarios.oblique``, docs/frictional-impacts.md, "Against MuJoCo")."""

from __future__ import annotations

from pathlib import Path

import click

from impactqp.scenarios.cli.arguments import check_jobs, emit_json, output_directory, robot_options

OUT = "out/oblique"
FILES = ("oblique.json", "oblique.md")


@click.command()
@click.option("--grid", "grid_name", default="full", show_default=True,
              help="The trials: full (5 v_t/v_n x 3 mu x 2 postures + the paper's 10 v_t) or small (3 trials).")
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--out", "out_dir", default=OUT, show_default=True, help="Output directory (oblique.json, oblique.md).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@robot_options
def oblique(grid_name, jobs, out_dir, as_json, choice):
    """Oblique impacts of a fixed-base arm on MuJoCo's wall: predicted (CRB, GM, classical) against
    simulated tangential impulse, post-impact tangential velocity and contact mode."""
    # lazy: the command line loads what a command needs when it runs
    import json

    from impactqp.controller.measured.atomic import write_text_atomic
    from impactqp.scenarios.oblique import grid_named, markdown, run_oblique_study

    grid = grid_named(grid_name)
    out = output_directory(out_dir, "--out")
    report = run_oblique_study(choice, grid, check_jobs(jobs))
    text = markdown(report)
    write_text_atomic(Path(out) / FILES[0], json.dumps(report, indent=2, allow_nan=False) + "\n")
    write_text_atomic(Path(out) / FILES[1], text)
    if as_json:
        emit_json(report)
        return
    click.echo(text, nl=False)
    click.echo(f"{' and '.join(FILES)} written to {out}")
