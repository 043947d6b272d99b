"""The ``impactqp`` command line.

Every command validates its input; bad input gets one line on stderr and exit code 2, never a
traceback. ``--json`` prints machine-readable output on stdout.
"""

from __future__ import annotations


import click
import numpy as np

from impactqp.controller.model.jump import METHODS
from impactqp.controller.model.postures import POSTURES
from impactqp.controller.model.robot import InvalidStateError, SingularPostureError

from impactqp.scenarios.cli.arguments import EXIT_BAD_INPUT, BadInput, emit_json, parse_vector

@click.group()
def cli():
    """Impact-aware QP control of a Franka Panda (Wang, Dehio, Kheddar, RA-L 2022)."""


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list.")
def postures(as_json):
    """List the named impact postures, their contact point and the wall normal."""
    from impactqp.controller.model.robot import PandaModel

    robot = PandaModel()
    rows = [
        {
            "name": p.name,
            "q": p.q.tolist(),
            "contact_point": robot.contact_point(p.q).tolist(),
            "normal": p.surface.normal.tolist(),
            "description": p.description,
        }
        for p in POSTURES.values()
    ]
    if as_json:
        emit_json(rows)
        return
    for row in rows:
        click.echo(f"{row['name']:<12} {row['description']}")
        click.echo(f"  q             = {np.array2string(np.array(row['q']), precision=4)}")
        click.echo(f"  contact point = {np.array2string(np.array(row['contact_point']), precision=4)} m")
        click.echo(f"  normal        = {row['normal']}")


@cli.command()
@click.option("--posture", "posture_name", help="A named posture (see `impactqp postures`).")
@click.option("--q", "q_text", help="Joint positions Q1,...,Q7 (rad).")
@click.option("--normal", "normal_text", required=True, help="Surface normal NX,NY,NZ towards the robot.")
@click.option("--speed", type=float, required=True, help="Approach speed along -normal (m/s), > 0.")
@click.option("--tangential", "tangential_text", help="Tangential velocity VX,VY,VZ (m/s), orthogonal to the normal.")
@click.option("--restitution", type=float, default=0.0, show_default=True, help="Coefficient of restitution in [0, 1].")
@click.option("--method", type=click.Choice([*METHODS, "all"]), default="all", show_default=True)
@click.option("--json", "as_json", is_flag=True)
def predict(posture_name, q_text, normal_text, speed, tangential_text, restitution, method, as_json):
    """Predict the impact-induced joint-velocity jump at a posture."""
    from impactqp.controller.model.prediction import ImpactQuery, predict_all

    if (posture_name is None) == (q_text is None):
        raise BadInput("give exactly one of --posture NAME or --q Q1,...,Q7")
    if posture_name is not None:
        if posture_name not in POSTURES:
            raise BadInput(f"unknown posture {posture_name!r}; known: {', '.join(POSTURES)}")
        q = POSTURES[posture_name].q
    else:
        q = parse_vector(q_text, 7, "--q")
    tangential = parse_vector(tangential_text, 3, "--tangential") if tangential_text else np.zeros(3)
    query = ImpactQuery.from_speed(
        q, parse_vector(normal_text, 3, "--normal"), speed, tangential, restitution
    )
    methods = METHODS if method == "all" else (method,)
    report = predict_all(query, methods)
    if as_json:
        emit_json(report)
        return
    click.echo(f"q                   = {np.array2string(np.array(report['q']), precision=4)}")
    click.echo(f"contact point       = {np.array2string(np.array(report['contact_point']), precision=4)} m")
    click.echo(f"normal              = {np.array2string(np.array(report['normal']), precision=4)}")
    click.echo(f"pre-impact velocity = {np.array2string(np.array(report['pre_impact_velocity']), precision=4)} m/s")
    click.echo(f"restitution         = {report['restitution']}   cond(M) = {report['cond_M']:.0f}")
    header = f"{'method':<17}" + "".join(f"{f'dq{i}':>9}" for i in range(1, 8)) + "   impulse (N s)"
    click.echo(header)
    for name, res in report["methods"].items():
        dq = "".join(f"{x:9.4f}" for x in res["dq_jump"])
        imp = " ".join(f"{x:7.4f}" for x in res["impulse"])
        click.echo(f"{name:<17}{dq}   [{imp}]")


@cli.command()
@click.option("--json", "as_json", is_flag=True, help='Print {"rows": [...]}.')
@click.option("--only", default="", help="Run only the rows whose name starts with this prefix.")
def bench(as_json, only):
    """Benchmark table: median and p99 of every tracked speed and accuracy figure."""
    from impactqp.scenarios.bench import run_benchmarks

    rows = run_benchmarks(only, progress=not as_json)
    if as_json:
        emit_json({"rows": rows})
        return
    click.echo(f"{'name':<38}{'unit':<16}{'median':>14}{'p99':>14}")
    for row in rows:
        if row["median"] is None:  # a row that could not be measured says why
            click.echo(f"{row['name']:<38}{row['unit']:<16}{'n/a':>14}{'n/a':>14}  {row.get('note', '')}")
            continue
        click.echo(f"{row['name']:<38}{row['unit']:<16}{row['median']:>14.4g}{row['p99']:>14.4g}")


@cli.command()
@click.option("--out", "out_dir", default="out/demo", show_default=True, help="Output directory.")
@click.option("--jobs", type=int, default=2, show_default=True, help="Worker processes.")
def demo(out_dir, jobs):
    """The main scenario: a short simulated campaign and the maximum speeds of one posture.

    Campaign: 3 postures x 5 normal speeds + 4 tangential speeds, Table I and the figures in
    --out; then `max-speed --posture elbow_up` (closed form, QP-limited and simulated).
    """
    from impactqp.scenarios.cli.simulation_commands import max_speed_text, run_campaign, run_max_speed

    table = run_campaign(None, None, "0.03,0.06,0.09,0.12", None, jobs, out_dir, True)
    click.echo(table.text())
    click.echo(f"dataset, Table I and figures written to {out_dir}\n")
    report = run_max_speed("elbow_up", "crb", 0.0, 0.015, None, None, None, jobs, 0.005, True)
    click.echo(max_speed_text(report))


from impactqp.scenarios.cli.simulation_commands import campaign, max_speed, simulate  # noqa: E402

cli.add_command(simulate)
cli.add_command(campaign)
cli.add_command(max_speed)

from impactqp.scenarios.cli.dataset_commands import dataset, diagnose  # noqa: E402

cli.add_command(dataset)
cli.add_command(diagnose)


def main(argv: list[str] | None = None) -> int:
    try:
        code = cli.main(args=argv, prog_name="impactqp", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("impactqp: aborted", err=True)
        return 1
    except click.ClickException as exc:
        click.echo(f"impactqp: error: {exc.format_message()}", err=True)
        return EXIT_BAD_INPUT
    except (InvalidStateError, SingularPostureError, ValueError, KeyError, FileNotFoundError) as exc:
        message = exc.args[0] if exc.args else str(exc)
        click.echo(f"impactqp: error: {message}", err=True)
        return EXIT_BAD_INPUT
    return code if isinstance(code, int) else 0

