"""``impactqp oblique``: the frictional impact law against MuJoCo's simulated wall
(``scenarios.oblique``, docs/frictional-impacts.md, "Against MuJoCo"), on the default plant or
with a joint impedance servo (``--servo-stiffness``); with ``--qp-speed`` the robust friction rows
against it, at the QP's own highest speed (``scenarios.oblique_campaign``); with
``--inverse-inertia`` the simulated plant's W at the contact against the predictors'
(``scenarios.oblique_inertia``)."""

from __future__ import annotations

from pathlib import Path

import click

from impactqp.scenarios.cli.arguments import check_jobs, emit_json, output_directory, robot_options

OUT = "out/oblique"
FILES = ("oblique.json", "oblique.md")
QP_SPEED_FILES = ("qp-speed.json", "qp-speed.md")
INVERSE_INERTIA_FILES = ("inverse-inertia.json", "inverse-inertia.md")
QP_SPEED_JUMP_MODEL = "classical"
"""The campaign's default rows: the classical law, MuJoCo's rigid plant's own impact (docs/frictional-impacts.md)."""


@click.command()
@click.option("--grid", "grid_name", default="full", show_default=True,
              help="The trials: full (5 v_t/v_n x 3 mu x 2 postures, + the paper's 10 v_t without --qp-speed) "
                   "or small (3 trials; 1 with --qp-speed).")
@click.option("--qp-speed", is_flag=True,
              help="The robust friction rows against MuJoCo: each trial's QP at its own highest speed, "
                   "with the robust rows and with the normal-only rows (qp-speed.json, qp-speed.md).")
@click.option("--inverse-inertia", is_flag=True,
              help="The simulated plant's inverse inertia at the contact, per servo and pulse duration, against "
                   "W_gm and W_crb (inverse-inertia.json, inverse-inertia.md).")
@click.option("--servo-stiffness", "stiffness_text",
              help="K1,...,Kn (N m/rad): the trials' servo a joint impedance of these stiffnesses "
                   "(e.g. a Franka's default 3000,3000,3000,2500,2500,2000,2000) instead of the default plant's.")
@click.option("--jump-model", default=None,
              help=f"With --qp-speed: the impact rows' predictor (crb, gm, classical, robust) [default: {QP_SPEED_JUMP_MODEL}].")
@click.option("--jobs", type=int, default=1, show_default=True, help="Worker processes.")
@click.option("--out", "out_dir", default=OUT, show_default=True, help="Output directory.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@robot_options
def oblique(choice, as_json, **options):
    """Oblique impacts of a fixed-base arm on MuJoCo's wall: predicted (CRB, GM, classical) against
    simulated tangential impulse, post-impact tangential velocity and contact mode; with
    --qp-speed, the largest post-impact joint velocity at the QP's own highest speed, robust
    friction rows against normal-only rows; with --inverse-inertia, the simulated arm's inverse
    inertia at the contact against the predictors'."""
    # lazy: the command line loads what a command needs when it runs
    import json

    from impactqp.controller.measured.atomic import write_text_atomic
    from impactqp.controller.model.validation import BadInputError

    grid_name, qp_speed, inverse_inertia, jump_model, jobs, out_dir = (
        options[key] for key in ("grid_name", "qp_speed", "inverse_inertia", "jump_model", "jobs", "out_dir"))
    stiffness_text = options["stiffness_text"]
    if inverse_inertia and (qp_speed or grid_name != "full" or stiffness_text is not None or jump_model is not None):
        raise BadInputError("--inverse-inertia runs its own study: not with --qp-speed, --grid, --servo-stiffness or --jump-model")
    if qp_speed and stiffness_text is not None:
        raise BadInputError("--servo-stiffness sets the servo of the oblique study; not with --qp-speed")
    if inverse_inertia:
        from impactqp.scenarios.oblique import fixed_base
        from impactqp.scenarios.oblique_inertia import markdown, run_inverse_inertia_study

        fixed_base(choice)
        out = output_directory(out_dir, "--out")
        report, files = run_inverse_inertia_study(choice), INVERSE_INERTIA_FILES
    elif qp_speed:
        from impactqp.scenarios.oblique import fixed_base
        from impactqp.scenarios.oblique_campaign import markdown, qp_speed_grid_named, run_qp_speed_campaign

        grid = qp_speed_grid_named(grid_name, QP_SPEED_JUMP_MODEL if jump_model is None else jump_model)
        fixed_base(choice)
        out = output_directory(out_dir, "--out")
        report, files = run_qp_speed_campaign(choice, grid, check_jobs(jobs)), QP_SPEED_FILES
    else:
        from impactqp.scenarios.oblique import grid_named, markdown, run_oblique_study
        from impactqp.scenarios.oblique_inertia import with_plant_row

        if jump_model is not None:
            raise BadInputError("--jump-model chooses the rows of --qp-speed; give --qp-speed too")
        grid = grid_named(grid_name)
        plant = None if stiffness_text is None else servo_plant(stiffness_text, len(choice.robot.joints))
        out = output_directory(out_dir, "--out")
        report = with_plant_row(run_oblique_study(choice, grid, check_jobs(jobs), plant), choice, plant)
        files = FILES
    text = markdown(report)
    write_text_atomic(Path(out) / files[0], json.dumps(report, indent=2, allow_nan=False) + "\n")
    write_text_atomic(Path(out) / files[1], text)
    if as_json:
        emit_json(report)
        return
    click.echo(text, nl=False)
    click.echo(f"{' and '.join(files)} written to {out}")


def servo_plant(text: str, joints: int):
    """The default plant with the joint impedance servo of ``--servo-stiffness`` (one stiffness per joint)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.cli.arguments import parse_vector
    from impactqp.sim.plant import PlantParameters

    return PlantParameters(servo_stiffness=tuple(parse_vector(text, joints, "--servo-stiffness")))
