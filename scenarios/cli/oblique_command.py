"""``impactqp oblique``: the frictional impact law against MuJoCo's simulated wall
(``scenarios.oblique``, docs/frictional-impacts.md, "Against MuJoCo"); with ``--qp-speed`` the
robust friction rows against it, at the QP's own highest speed (``scenarios.oblique_campaign``)."""

from __future__ import annotations

from pathlib import Path

import click

from impactqp.scenarios.cli.arguments import check_jobs, emit_json, output_directory, robot_options

OUT = "out/oblique"
FILES = ("oblique.json", "oblique.md")
QP_SPEED_FILES = ("qp-speed.json", "qp-speed.md")
QP_SPEED_JUMP_MODEL = "classical"
"""The campaign's default rows: the classical law, MuJoCo's rigid plant's own impact (docs/frictional-impacts.md)."""


@click.command()
@click.option("--grid", "grid_name", default="full", show_default=True,
              help="The trials: full (5 v_t/v_n x 3 mu x 2 postures, + the paper's 10 v_t without --qp-speed) "
                   "or small (3 trials; 1 with --qp-speed).")
@click.option("--qp-speed", is_flag=True,
              help="The robust friction rows against MuJoCo: each trial's QP at its own highest speed, "
                   "with the robust rows and with the normal-only rows (qp-speed.json, qp-speed.md).")
@click.option("--jump-model", default=None,
              help=f"With --qp-speed: the impact rows' predictor (crb, gm, classical, robust) [default: {QP_SPEED_JUMP_MODEL}].")
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--out", "out_dir", default=OUT, show_default=True, help="Output directory.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@robot_options
def oblique(grid_name, qp_speed, jump_model, jobs, out_dir, as_json, choice):
    """Oblique impacts of a fixed-base arm on MuJoCo's wall: predicted (CRB, GM, classical) against
    simulated tangential impulse, post-impact tangential velocity and contact mode; with
    --qp-speed, the largest post-impact joint velocity at the QP's own highest speed, robust
    friction rows against normal-only rows."""
    # lazy: the command line loads what a command needs when it runs
    import json

    from impactqp.controller.measured.atomic import write_text_atomic
    from impactqp.controller.model.validation import BadInputError

    if qp_speed:
        from impactqp.scenarios.oblique import fixed_base
        from impactqp.scenarios.oblique_campaign import markdown, qp_speed_grid_named, run_qp_speed_campaign

        grid = qp_speed_grid_named(grid_name, jump_model or QP_SPEED_JUMP_MODEL)
        fixed_base(choice)
        out = output_directory(out_dir, "--out")
        report, files = run_qp_speed_campaign(choice, grid, check_jobs(jobs)), QP_SPEED_FILES
    else:
        from impactqp.scenarios.oblique import grid_named, markdown, run_oblique_study

        if jump_model is not None:
            raise BadInputError("--jump-model chooses the rows of --qp-speed; give --qp-speed too")
        grid = grid_named(grid_name)
        out = output_directory(out_dir, "--out")
        report, files = run_oblique_study(choice, grid, check_jobs(jobs)), FILES
    text = markdown(report)
    write_text_atomic(Path(out) / files[0], json.dumps(report, indent=2, allow_nan=False) + "\n")
    write_text_atomic(Path(out) / files[1], text)
    if as_json:
        emit_json(report)
        return
    click.echo(text, nl=False)
    click.echo(f"{' and '.join(files)} written to {out}")
