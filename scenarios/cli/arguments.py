"""Command-line arguments and output shared by the ``impactqp`` commands.

Bad input raises :class:`BadInput`: one line on stderr and exit code 2 (``scenarios.cli.main``).
"""

from __future__ import annotations

import json

import click
import numpy as np

EXIT_BAD_INPUT = 2


class BadInput(click.ClickException):
    exit_code = EXIT_BAD_INPUT


def parse_vector(text: str, size: int | None, what: str) -> np.ndarray:
    """Parse 'a,b,c' into a float array, checking the count and finiteness."""
    try:
        values = np.array([float(x) for x in text.split(",")], dtype=float)
    except ValueError:
        raise BadInput(f"{what} must be comma-separated numbers, got {text!r}") from None
    if size is not None and values.size != size:
        raise BadInput(f"{what} must have {size} values, got {values.size}")
    if not np.all(np.isfinite(values)):
        raise BadInput(f"{what} contains a non-finite value")
    return values


def parse_list(text: str, what: str) -> list[float]:
    return parse_vector(text, None, what).tolist()


def emit_json(obj) -> None:
    click.echo(json.dumps(obj, indent=2))


def load_plant(path: str | None):
    """The plant of ``--plant FILE`` (JSON overrides of ``sim.plant.PlantParameters``), or
    None without a file."""
    from impactqp.sim.plant import PlantParameterError, PlantParameters

    if path is None:
        return None
    try:
        return PlantParameters.from_json(path)
    except PlantParameterError as error:
        raise BadInput(f"--plant: {error}") from None


def check_jobs(value: int) -> int:
    """``--jobs N``: a number of worker processes, >= 1."""
    if value < 1:
        raise BadInput(f"--jobs must be >= 1, got {value}")
    return value
