"""Command-line arguments and output shared by the ``impactqp`` commands.

Parsing errors raise ``BadInputError`` (``controller/model/validation.py``): one line on stderr and
exit code 2 (``scenarios.cli.main``). Every file or directory argument is checked here, before
any work starts.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import click
import numpy as np

from impactqp.controller.model.files import regular_file
from impactqp.controller.model.validation import MAX_TRIALS, BadInputError, repeated
from impactqp.scenarios.cli import command_result

max_trials_option = click.option(
    "--max-trials", "max_trials", type=int, default=MAX_TRIALS, show_default=True,
    help="The most trials the request may hold; a larger one is refused before any work (raise it to run more).",
)


def parse_vector(text: str, size: int | None, what: str) -> np.ndarray:
    """Parse 'a,b,c' into a float array, checking the count and finiteness."""
    try:
        values = np.array([float(x) for x in text.split(",")], dtype=float)
    except ValueError:
        raise BadInputError(f"{what} must be comma-separated numbers, got {text!r}") from None
    if size is not None and values.size != size:
        raise BadInputError(f"{what} must have {size} values, got {values.size}")
    if not np.all(np.isfinite(values)):
        raise BadInputError(f"{what} contains a non-finite value")
    return values


MAX_LIST_ENTRIES = 100
"""Most values of a list option (--speeds, --tangential): each one a simulated condition."""


def parse_list(text: str, what: str) -> list[float]:
    """'a,b,c' as a list of distinct finite numbers, one to ``MAX_LIST_ENTRIES`` of them."""
    if not text.strip():
        raise BadInputError(f"{what} is empty: give comma-separated numbers, or leave the option out")
    values = parse_vector(text, None, what).tolist()
    if len(values) > MAX_LIST_ENTRIES:
        raise BadInputError(f"{what} has {len(values)} values; at most {MAX_LIST_ENTRIES}")
    twice = repeated(values)
    if twice:
        raise BadInputError(f"{what} repeats {', '.join(f'{v:g}' for v in twice)}")
    return values


def emit_json(obj) -> None:
    """Strict JSON on stdout: a non-finite number is an internal error, never printed as NaN.
    The JSON is the command's result: once it is being written, the work is done
    (``command_result``), so that a stop signal in the middle of the write neither cuts it nor
    turns the exit code into 130."""
    text = json.dumps(obj, indent=2, allow_nan=False)
    command_result.result_written()
    click.echo(text)


def bar_progress(bar):
    """A ``progress(done, total)`` callback (``sim.generation.generate_dataset``) that drives the
    tqdm progress bar ``bar``."""

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    return progress


def input_file(path: str, what: str) -> Path:
    """An existing, readable regular file."""
    p = regular_file(path, f"{what}:")
    if not os.access(p, os.R_OK):
        raise BadInputError(f"{what}: {path} is not readable")
    return p


def input_directory(path: str, what: str) -> Path:
    """An existing, readable directory."""
    p = Path(path)
    if not p.is_dir():
        raise BadInputError(f"{what}: {path} is not a directory")
    if not os.access(p, os.R_OK | os.X_OK):
        raise BadInputError(f"{what}: {path} is not readable")
    return p


def _writable_parent(p: Path, what: str) -> None:
    parent = p.parent if str(p.parent) else Path(".")
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise BadInputError(f"{what}: {p} lies under {parent}, which is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise BadInputError(f"{what}: cannot write under {parent} (permission denied)")


def _not_an_input(path: Path, what: str, inputs) -> None:
    """Bad input when the output ``path`` is one of ``inputs`` (files or directories), contains
    one, or is an existing file inside an input directory: an output never overwrites an input."""
    target = Path(os.path.realpath(path))
    for source in inputs:
        if source is None:
            continue
        origin = Path(os.path.realpath(source))
        inside_input = origin.is_dir() and target.is_relative_to(origin) and target.exists()
        if target == origin or origin.is_relative_to(target) or inside_input:
            raise BadInputError(f"{what}: {path} would overwrite the input {source}; write elsewhere")


def output_directory(path: str, what: str, inputs=()) -> Path:
    """A directory that exists and is writable, or can be created, and is not, nor holds, one of
    ``inputs``. An empty path is not the working directory: it is bad input."""
    p = _given_path(path, what, "directory")
    _not_an_input(p, what, inputs)
    if p.exists():
        if not p.is_dir():
            raise BadInputError(f"{what}: {path} exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise BadInputError(f"{what}: {path} is not writable")
        return p
    _writable_parent(p, what)
    return p


def _given_path(path: str, what: str, kind: str) -> Path:
    """``path`` as a Path, refusing an empty or blank one (Path("") would be the working directory)."""
    if not str(path).strip():
        raise BadInputError(f"{what} is empty: give a {kind}")
    return Path(path)


def output_file(path: str, what: str, inputs=()) -> Path:
    """A file that can be written atomically: not a directory nor a special file, in a writable
    directory, not one of ``inputs`` nor an existing file inside an input directory."""
    p = _given_path(path, what, "file")
    _not_an_input(p, what, inputs)
    if p.is_dir():
        raise BadInputError(f"{what}: {path} is a directory")
    if p.exists() and not p.is_file():  # an atomic write would replace the FIFO or device itself
        raise BadInputError(f"{what}: {path} is a special file (a FIFO, a device or a socket), not a file to write")
    _writable_parent(p, what)
    return p


def video_output(path: str) -> Path:
    """``--video FILE``: a writable file name of a video format (``scenarios.video.VIDEO_SUFFIXES``),
    with an offscreen renderer available."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.scenarios.video import check_video_suffix, offscreen_backend_problem

    p = check_video_suffix(output_file(path, "--video"))
    problem = offscreen_backend_problem()
    if problem is not None:
        raise BadInputError(f"--video: {problem}")
    return p


def load_plant(path: str | None):
    """The plant of ``--plant NAME|FILE``: a built-in plant's name (``sim.plant.built_in_plants``:
    ``identified_panda``) or a JSON file of overrides of ``sim.plant.PlantParameters``; None
    without either."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.sim.plant import PlantParameterError, PlantParameters, built_in_plants

    if path is None:
        return None
    try:
        if not Path(path).exists() and (str(path) in built_in_plants() or not Path(path).suffix):
            return PlantParameters.named(str(path))  # a name: an unknown one lists the built-ins
        input_file(path, "--plant")
        return PlantParameters.from_json(path)
    except PlantParameterError as error:
        raise BadInputError(f"--plant: {error}") from None


def max_jobs() -> int:
    """Most worker processes a command starts: four per core (each holds a model and a scene)."""
    return 4 * (os.cpu_count() or 1)


def check_jobs(value: int) -> int:
    """``--jobs N``: a number of worker processes in [1, max_jobs()]."""
    if not 1 <= value <= max_jobs():
        raise BadInputError(f"--jobs must lie in [1, {max_jobs()}] (four per core), got {value}")
    return value


def robot_choice(robot: str, tool: str, humanoid: bool = False):
    """The ``controller.model.choice.RobotChoice`` of ``--robot NAME|FILE`` (a built-in robot or a
    robot .toml file) and ``--tool NAME|FILE`` (bad input names the choices). A floating-base
    robot (``choice.robot.floating``: the G1) is taken only where the command takes one
    (``humanoid``); it carries no tool (``RobotChoice.of``)."""
    # lazy: loads Pinocchio, only when a command runs
    from impactqp.controller.model.choice import RobotChoice
    from impactqp.controller.model.robot_description import robot_description

    description = robot_description(robot)
    if description.floating and not humanoid:
        raise BadInputError(f"--robot {description.name} (a floating base) works with predict, simulate, campaign, "
                            "max-speed and run only")
    return RobotChoice.of(description, tool)


def robot_help(humanoid: bool) -> str:
    """The help of ``--robot``: the built-in robots (:data:`ROBOTS` of ``robot_description``) or a
    robot file, and where a floating base is taken."""
    # lazy: the command line loads what a command needs when it runs
    from impactqp.controller.model.robot_description import ROBOTS

    where = "docs/floating-base.md" if humanoid else "a floating base only with predict, simulate, campaign, max-speed and run"
    return f"The robot: {', '.join(ROBOTS)} or a robot .toml file (docs/robots.md; {where})."


def robot_options(command=None, *, humanoid: bool = False):
    """Add ``--robot`` and ``--tool`` to a click command, which receives them as one ``choice``
    (a ``controller.model.choice.RobotChoice``; with ``humanoid`` it may be a floating-base
    robot's, ``choice.robot.floating``) instead of two strings. Use as ``@robot_options`` or
    ``@robot_options(humanoid=True)``."""
    if command is None:
        return functools.partial(robot_options, humanoid=humanoid)

    @functools.wraps(command)
    def with_choice(*args, robot: str, tool: str, **kwargs):
        return command(*args, choice=robot_choice(robot, tool, humanoid), **kwargs)

    with_choice = click.option(
        "--tool", default="impact_tip", show_default=True,
        help="The tool: impact_tip, franka_hand, pad, or a .json/.toml tool file (docs/robots.md).",
    )(with_choice)
    return click.option("--robot", default="panda", show_default=True, help=robot_help(humanoid))(with_choice)


FLOATING_BASE = "a floating-base robot (docs/floating-base.md)"


def reject_options(names, where: str = FLOATING_BASE) -> None:
    """Bad input when one of the options ``names`` (click parameter names), which do not apply
    ``where`` (by default: to a floating-base robot), was given."""
    ctx = click.get_current_context()
    for name in names:
        if ctx.get_parameter_source(name) not in (None, click.core.ParameterSource.DEFAULT):
            option = next(p for p in ctx.command.params if p.name == name).opts[0]
            raise BadInputError(f"{option} does not apply to {where}")


def stance_names(robot, text: str | None) -> tuple[str, ...]:
    """Comma-separated stance names of the floating-base ``robot`` (all when None), each checked: its
    postures are its description's stances."""
    stances = robot.stances
    names = tuple(stances) if text is None else tuple(s.strip() for s in text.split(","))
    for name in names:
        if name not in stances:
            raise BadInputError(f"unknown posture {name!r} for the {robot.name}; known: {', '.join(stances)}")
    return names
