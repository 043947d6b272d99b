"""``impactqp dataset validate|generate|import-franka`` and ``impactqp diagnose``: measured data against the
simulation (dataset format: ``controller.measured.dataset`` and docs/dataset.md)."""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import click

from impactqp.controller.model.validation import BadInputError, number_in_range
from impactqp.scenarios.cli.arguments import (
    check_jobs,
    emit_json,
    input_directory,
    load_plant,
    max_trials_option,
    output_directory,
    output_file,
    parse_list,
    parse_vector,
    robot_options,
)
from impactqp.scenarios.cli.stderr_log import LOGGER, show_progress


@click.group()
def dataset():
    """Impact datasets: validate a log directory, or generate one in simulation."""


@dataset.command("validate")
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--json", "as_json", is_flag=True)
@click.pass_context
def validate_command(ctx, directory, as_json):
    """Report every problem per trial; never modifies the data. Exit code 1 when any is found.
    Each file is read once, however many entries name it; a progress bar goes to stderr on a
    terminal (never into a redirected stream)."""
    # lazy: the command line loads what a command needs when it runs
    from tqdm import tqdm

    from impactqp.controller.measured.dataset_check import validate

    input_directory(directory, "DIRECTORY")
    show = show_progress()
    bars = []  # on stderr, on a terminal only

    def progress(done: int, total: int) -> None:
        if not bars:
            bars.append(tqdm(total=total, disable=None if show else True, desc="trials", unit="trial", file=sys.stderr))
        bars[0].update(done - bars[0].n)

    try:
        problems = validate(directory, progress=progress)
    finally:
        for bar in bars:
            bar.close()
    count = sum(len(v) for v in problems.values())
    if as_json:
        emit_json({"valid": count == 0, "problems": problems})
    else:
        for key, items in problems.items():
            if key == "dataset" and not items:
                continue
            click.echo(f"{key}: {'ok' if not items else ''}")
            for item in items:
                click.echo(f"  - {item}")
        click.echo(f"{count} problem(s) in {len(problems) - 1} trial(s)")
    if count:
        ctx.exit(1)


@dataset.command("generate")
@click.argument("out", required=False, default="out/generate", type=click.Path(file_okay=False))
@click.option("--plant", "plant_file", type=click.Path(dir_okay=False), help="Plant: a JSON file of overrides or a built-in name (identified_panda).")
@click.option("--postures", help="Comma-separated posture names (default: all).")
@click.option("--speeds", help="Comma-separated normal speeds, m/s (default 0.08,0.10,0.12,0.15,0.18).")
@click.option("--tangential", help="Comma-separated tangential speeds, m/s, at v_n = 0.12 (direction n x e_z).")
@click.option("--repeats", type=int, default=1, show_default=True)
@click.option("--noise-dq", type=float, default=0.0042, show_default=True, help="Encoder noise std on dq (rad/s).")
@click.option("--noise-tau", type=float, default=0.05, show_default=True, help="Noise std on tau (N m).")
@click.option("--dq-step", type=float, default=0.0, show_default=True,
              help="Quantise the logged dq to this step, rad/s, as an encoder-based velocity (0: none): "
                   "the plant's sensor_velocity_step at every joint; the manifest declares it (encoder_step).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--jobs", type=int, default=1, show_default=True)
@click.option("--json", "as_json", is_flag=True)
@max_trials_option
@robot_options
def generate_command(out, postures, speeds, tangential, as_json, choice, **noise):
    """Simulate a dataset of the robot with the tool (plant overrides with --plant) in the
    measured-data format, in OUT (default out/generate); the manifest records the robot and the
    tool."""
    from tqdm import tqdm  # lazy: the command line loads what a command needs when it runs

    from impactqp.sim.generation import DatasetRequest, generate_dataset

    plant_file, jobs, dq_step = noise.pop("plant_file"), noise.pop("jobs"), noise.pop("dq_step")
    output_directory(out, "OUT")
    plant = quantised_plant(load_plant(plant_file), dq_step, len(choice.robot.joints))  # None: the nominal plant
    names = list(choice.check_postures(p.strip() for p in postures.split(","))) if postures else list(choice.robot.postures)
    speed_list = parse_list(speeds, "--speeds") if speeds is not None else None
    tangential_list = parse_list(tangential, "--tangential") if tangential is not None else []
    check_jobs(jobs)
    bars = []  # the progress bar appears with the first finished trial, after validation

    def progress(done: int, total: int) -> None:
        if not bars:
            bars.append(tqdm(total=total, disable=None if show_progress(as_json) else True, desc="trials", unit="trial"))
        bars[0].update(done - bars[0].n)

    try:
        request = DatasetRequest(
            plant=plant, postures=names, speeds=speed_list, tangential=tangential_list, choice=choice,
            **noise,  # repeats, noise_dq, noise_tau, seed: the request's fields of the same names
        )
        entries = generate_dataset(out, request, jobs=jobs, progress=progress)
    finally:
        for bar in bars:
            bar.close()
    if as_json:
        emit_json({"out": str(out), "trials": [e.to_dict() for e in entries]})
    else:
        click.echo(f"wrote {len(entries)} trial(s) to {out}")


def quantised_plant(plant, dq_step: float, joints: int):
    """``plant`` (None: the nominal one) with dq quantised to ``dq_step`` (rad/s, ``--dq-step``) at
    every one of ``joints`` joints (``sensor_velocity_step``); ``plant`` itself for a step of 0.
    A plant that quantises already, given a step as well, is bad input: the step comes once."""
    from dataclasses import replace  # lazy: the command line loads what a command needs when it runs

    from impactqp.sim.plant import RANGES, PlantParameters

    if dq_step == 0.0:
        return plant
    number_in_range(dq_step, *RANGES["sensor_velocity_step"][:2], "the velocity quantisation step --dq-step", "rad/s")
    if plant is not None and any(plant.sensor_velocity_step):
        raise BadInputError("--dq-step: the plant quantises dq already (sensor_velocity_step); give the step once")
    return replace(plant or PlantParameters(), sensor_velocity_step=(dq_step,) * joints)


@dataset.command("import-franka")
@click.argument("out", type=click.Path(file_okay=False))
@click.argument("logs", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--surface-point", required=True, help="A point X,Y,Z (m, world) of the surface hit.")
@click.option("--surface-normal", required=True, help="The surface normal NX,NY,NZ, towards the robot.")
@click.option("--reference-speed", type=float, help="Reference normal speed (m/s) of every log (default: estimated).")
@click.option("--json", "as_json", is_flag=True)
@robot_options
def import_franka_command(out, logs, surface_point, surface_normal, reference_speed, as_json, choice):
    """Import libfranka logs (franka::logToCSV, one log per trial) of the robot hitting with the
    tool as a dataset in OUT."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.measured.franka_log import import_franka_logs
    from impactqp.controller.model.postures import Surface
    from impactqp.controller.model.validation import unit_normal

    output_directory(out, "OUT", inputs=logs)
    surface = Surface(parse_vector(surface_point, 3, "--surface-point"), unit_normal(
        parse_vector(surface_normal, 3, "--surface-normal"), "--surface-normal"))
    entries = import_franka_logs(out, list(logs), surface, choice=choice, reference_speed=reference_speed)
    if as_json:
        emit_json({"out": str(out), "trials": [e.to_dict() for e in entries]})
        return
    for e in entries:
        click.echo(f"{e.id}: reference normal speed {e.reference_normal_speed:.3f} m/s, posture {e.posture or '-'}")
    click.echo(f"wrote {len(entries)} trial(s) to {out}")


@click.command()
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--json", "as_json", is_flag=True)
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write report.md and PNG figures here.")
@click.option("--save-plant", type=click.Path(dir_okay=False),
              help="Save the fitted plant (JSON) when causes are named; otherwise nothing is written, and "
                   "after the diagnosis's output the command ends with one line and exit code 2.")
@click.option("--plant", "plant_file", type=click.Path(dir_okay=False), help="Nominal plant to start from: a JSON file or a built-in name (identified_panda).")
@click.option("--max-speed", "max_speed", is_flag=True,
              help="Also simulate the highest feasible contact speed per posture, nominal and extended plant.")
@click.option("--causes", "cause_names",
              help="Comma-separated candidate causes the search considers (default: all; docs/diagnosis.md).")
@click.option("--jobs", type=int, default=1, show_default=True)
@max_trials_option
@robot_options
def diagnose(directory, as_json, report_dir, save_plant, plant_file, choice, **work):
    """What the simulation gets wrong on measured impacts, why, and the model change that fixes it.

    The robot and the tool are the manifest's; a --robot/--tool other than the default that
    disagrees with them is bad input."""
    max_speed, jobs, max_trials = work["max_speed"], work["jobs"], work["max_trials"]

    # lazy: the command line loads what a command needs when it runs
    from impactqp.sim.plant import PlantParameters

    input_directory(directory, "DIRECTORY")
    check_jobs(jobs)
    manifest = _readable_manifest(directory)
    _check_manifest_choice(directory, manifest, choice)
    if report_dir is not None:  # an empty one is refused, not ignored
        output_directory(report_dir, "--report", inputs=(directory, plant_file))
    if save_plant is not None:
        output_file(save_plant, "--save-plant", inputs=(directory, plant_file))
    nominal = load_plant(plant_file) or PlantParameters()
    _check_output_room(manifest, report_dir, save_plant, nominal)
    limits = DiagnosisLimits(jobs, max_trials, manifest, _candidate_causes(manifest, work["cause_names"]))
    result = _diagnose_with_progress(directory, nominal, limits, show=show_progress(as_json))
    summary = result.summary()
    speeds = None
    if max_speed:
        from impactqp.scenarios.diagnosis_report import feasible_speeds

        speeds = feasible_speeds(result, nominal, jobs=jobs)
        summary["max_speeds"] = [r.to_json() for r in speeds]
    if save_plant and result.explained:
        from dataclasses import replace

        replace(nominal.for_joints(len(result.choice.robot.joints)), **summary["parameters"]).to_json(save_plant)
    if report_dir:
        from impactqp.scenarios.diagnosis_report import write_report

        path = write_report(result, report_dir, speeds)
        if not as_json:
            click.echo(f"report written to {path}")
    if as_json:
        emit_json(summary)
    else:
        _print_diagnosis(result, summary, speeds)
    if save_plant and not result.explained:
        raise BadInputError(f"--save-plant: no cause named: no plant to save; nothing written to {save_plant}")


@dataclass(frozen=True)
class DiagnosisLimits:
    """How ``diagnose`` runs: its worker processes, its largest dataset, the manifest the command
    line's checks read already (None: unreadable, the diagnosis reports it) and its candidates."""

    jobs: int
    max_trials: int
    manifest: dict | None
    causes: list | None  # the candidate causes (None: the defaults of the dataset's robot, surface and tool)


def _diagnose_with_progress(directory, nominal, limits: DiagnosisLimits, show: bool):
    """The diagnosis of ``directory``, its steps on a progress bar (stderr, when it is a terminal
    and ``show``) above its notes (the stages, each model set of the search, each profile: the
    log's lines, written around the bar); the bar is wiped when an error ends the command, whose
    message is one line."""
    # lazy: the command line loads what a command needs when it runs
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    from impactqp.sim.diagnosis import diagnose as run_diagnosis
    from impactqp.sim.diagnosis.pipeline import STEPS

    bar = tqdm(total=len(STEPS), desc="diagnose", unit="step", disable=None if show else True)

    def progress(step: str) -> None:
        bar.set_postfix_str(step)
        bar.update(STEPS.index(step) - bar.n)

    try:
        with logging_redirect_tqdm([logging.getLogger(LOGGER)]):
            result = run_diagnosis(directory, nominal=nominal, jobs=limits.jobs, progress=progress,
                                   max_trials=limits.max_trials, manifest=limits.manifest, causes=limits.causes)
        bar.update(bar.total - bar.n)
    except BaseException:
        bar.leave = False
        raise
    finally:
        bar.close()
    return result


def _print_diagnosis(result, summary: dict, speeds) -> None:
    """The diagnosis as text: the message, the causes and their intervals, the candidates, the
    predictors, the feasible speeds and the skipped trials."""
    # lazy: the command line loads what a command needs when it runs
    import statistics
    import textwrap

    from impactqp.scenarios.diagnosis_report import trusted_speed_text
    from impactqp.scenarios.readable import boolean, number, parameters_text
    from impactqp.sim.diagnosis import interval_text

    click.echo(summary["message"])
    click.echo(
        f"causes: {', '.join(summary['causes']) or 'none'}  explained: {boolean(summary['explained'])}  "
        f"parameters: {parameters_text(summary['parameters'])}"
    )
    click.echo(
        f"average error (26) of the held-out replays: nominal {summary['baseline_error']:.4f} rad/s  "
        f"extended {summary['extended_error']:.4f} rad/s  gain {100 * summary['gain']:.1f} %"
    )
    residuals = summary["trial_residuals"]
    if len(residuals) > 1:
        worst = max(residuals, key=lambda r: r["residual"])
        click.echo(
            f"trial residuals (noise units): median {statistics.median(r['residual'] for r in residuals):.2f}, "
            f"largest {worst['residual']:.2f} ({worst['id']}); outliers: {', '.join(summary['outlier_trials']) or 'none'}"
        )
        outliers = set(summary["outlier_trials"])
        listed = ", ".join(f"{r['id']} {r['residual']:.2f}{' (stands out)' if r['id'] in outliers else ''}" for r in residuals)
        click.echo(textwrap.fill(listed, width=100, initial_indent="  ", subsequent_indent="  "))
    for k, step in enumerate(summary["steps"], start=1):
        taken = "selected" if step["selected"] else "taken" if step["accepted"] else "not taken"
        click.echo(
            f"step {k}: path {step['path'] + 1} {step['action']:<6} {step['cause']:<15} held-out residual "
            f"{step['heldout_error']:.4f} noise units  gain {100 * step['gain']:5.1f} %  {taken}"
        )
    for p in summary["parameter_intervals"]:
        click.echo(f"  {p['parameter']:<40} {number(p['value']):>10}  95 %: {interval_text(p['interval'])}")
    if summary["candidates"]:  # none on one trial: the selection holds trials out
        click.echo(f"{'candidate':<15}{'held-out residual (noise units)':>33}{'gain':>9}")
    for c in sorted(summary["candidates"], key=lambda c: -c["gain"]):
        click.echo(f"{c['cause']:<15}{c['heldout_error']:>33.4f}{100 * c['gain']:>8.1f}%")
    click.echo("predictors (average error (26), own impulse): " + ", ".join(f"{k} {v:.4f}" for k, v in summary["predictors"].items()))
    for r in speeds or []:
        click.echo(r.sentence())
    if speeds:
        click.echo(trusted_speed_text(result, speeds))
    for s in summary["skipped"]:
        click.echo(f"skipped {s['id']}: {s['reason']}")


def _readable_manifest(directory) -> dict | None:
    """The dataset's manifest, read once for the checks before the diagnosis and for the diagnosis
    itself; None when it cannot be read (the diagnosis reports its problem)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.measured.dataset import MANIFEST, DatasetError, load_manifest

    try:
        return load_manifest(Path(directory) / MANIFEST)
    except DatasetError:
        return None


def _candidate_causes(manifest: dict | None, text: str | None) -> list | None:
    """The default candidate causes of the dataset's robot, surface and tool named by ``--causes``
    (comma-separated, each once), in their default order; None without ``--causes`` or when the
    manifest cannot be read (the diagnosis reports its problem)."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.measured.dataset import DatasetError, parse_header
    from impactqp.sim.causes import default_causes

    if text is None or manifest is None:
        return None
    try:
        header = parse_header(manifest)
    except DatasetError:
        return None
    causes = default_causes(len(header.choice.robot.joints), header.surface.friction, header.choice.tool)
    known = [c.name for c in causes]
    names = [name.strip() for name in text.split(",")]
    for name in names:
        if name not in known:
            raise BadInputError(f"--causes: unknown cause {name!r}; the candidates are {', '.join(known)}")
    if len(set(names)) != len(names):
        raise BadInputError(f"--causes: a cause is named twice in {text!r}")
    return [c for c in causes if c.name in names]


def _check_output_room(manifest: dict | None, report_dir, save_plant, nominal) -> None:
    """Before the diagnosis: room for ``--report``'s files (``diagnosis_report.report_bytes`` of
    the ``manifest``'s postures and trials) and for ``--save-plant``'s (the nominal plant's JSON, at
    twice its length: a fitted value prints longer), ``check_room``; a manifest that cannot be
    read (None) is left to the diagnosis to report."""
    # lazy: the command line loads what a command needs when it runs
    import json

    from impactqp.controller.measured.dataset_writer import check_room

    if report_dir and manifest is not None:
        from impactqp.scenarios.diagnosis_report import report_bytes

        trials = manifest["trials"]
        postures = {trial.get("posture") for trial in trials if isinstance(trial, dict)}
        check_room(report_dir, report_bytes(len(postures), len(trials)), "the report's files")
    if save_plant:
        check_room(Path(save_plant).absolute().parent, 2 * len(json.dumps(nominal.to_dict(), indent=2)), "the plant file")


def _check_manifest_choice(directory, manifest: dict | None, choice) -> None:
    """Bad input when the ``manifest``'s robot has a floating base (the diagnosis replays an arm in its MuJoCo
    scene), or when a non-default ``choice`` (--robot, --tool) differs from the manifest's."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.measured.dataset import DatasetError, parse_header
    from impactqp.controller.model.robot_description import robot_description

    try:
        header = parse_header(manifest) if manifest is not None else None
    except DatasetError:
        header = None
    if header is None:
        return  # the diagnosis reports the manifest's own problem
    if robot_description(header.robot).floating:
        raise BadInputError(f"{directory} is a {robot_description(header.robot).name} dataset: diagnose replays and "
                            "fits the arms' trials, not a floating-base robot's")
    if choice.is_default:
        return
    if not header.choice.same_as(choice):
        raise BadInputError(
            f"the robot and tool of the dataset's manifest ({header.robot}, {header.tool.name}) differ from "
            f"--robot/--tool ({choice.robot.name}, {choice.tool.name})"
        )
