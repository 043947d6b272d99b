"""Chunked Parquet store of sweep rows, written atomically, with resume.

``DIR/sweep.json`` holds the identity of the sweep in ``DIR`` (its config, whether cells are
simulated and the plant of ``--plant``, :func:`identity`), the package version and the chunk size;
``DIR/chunk-NNNNNN.parquet`` holds the rows of cells [NNNNNN * chunk_size, ...). Each chunk is
written to a temporary file and moved into place (``controller.measured.atomic``), so a chunk on
disk is complete: resume skips it (and removes the temporary file a kill may leave) and a killed
sweep loses or duplicates no row. The Parquet metadata carries the identity and the package
version.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic
from impactqp.controller.model.validation import BadInputError

from .cells import Simulation
from .config import SweepConfig

CONFIG_FILE = "sweep.json"


def package_version() -> str:
    try:
        return version("impactqp")
    except PackageNotFoundError:
        return "unknown"


def chunk_path(out: Path, chunk: int) -> Path:
    return Path(out) / f"chunk-{chunk:06d}.parquet"


def identity(config: SweepConfig, simulation: Simulation | None) -> dict:
    """What makes two sweeps the same: the config, ``--simulate`` and the plant of ``--plant``
    (all its parameters; None for the nominal plant)."""
    plant = None if simulation is None or simulation.plant is None else simulation.plant.to_dict()
    return {"config": json.loads(config.canonical_json()), "simulate": simulation is not None, "plant": plant}


def prepare(out: Path, config: SweepConfig, simulation: Simulation | None, resume: bool, chunk_size: int) -> None:
    """Claim ``out`` for the sweep; on resume, refuse a directory of another sweep or chunking."""
    out = Path(out)
    stored = out / CONFIG_FILE
    ours = identity(config, simulation)
    if stored.exists():
        if not resume:
            raise BadInputError(f"{out} already holds a sweep; pass --resume or choose another --out")
        try:
            theirs = json.loads(stored.read_text())
        except (OSError, json.JSONDecodeError) as error:
            raise BadInputError(f"cannot read {stored}: {error}") from None
        for key, what in (("config", "the config"), ("simulate", "--simulate"), ("plant", "the --plant file")):
            if theirs.get(key) != ours[key]:
                raise BadInputError(f"{what} differs from the one of the sweep in {out}; cannot --resume")
        if theirs.get("chunk_size") != chunk_size:
            raise BadInputError(f"the sweep in {out} was written in chunks of another size; cannot --resume")
        for leftover in out.glob(".chunk-*"):  # the temporary file of a chunk being written when killed
            leftover.unlink()
        return
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(stored, json.dumps(ours | {"version": package_version(), "chunk_size": chunk_size}))


def done_chunks(out: Path, n_chunks: int) -> set[int]:
    return {c for c in range(n_chunks) if chunk_path(out, c).exists()}


def write_chunk(out: Path, chunk: int, columns: dict, sweep_identity: dict) -> Path:
    """Write the rows ``columns`` (name -> values) of ``chunk`` atomically."""
    table = pa.table(columns)
    table = table.replace_schema_metadata(
        {"impactqp.sweep": json.dumps(sweep_identity), "impactqp.version": package_version()}
    )
    return write_atomic(chunk_path(out, chunk), lambda tmp: pq.write_table(table, tmp))


def read_table(out: Path) -> pa.Table:
    """All rows of the sweep in ``out``, sorted by cell."""
    paths = sorted(Path(out).glob("chunk-*.parquet"))
    if not paths:
        raise BadInputError(f"{out} holds no sweep chunk")
    table = pa.concat_tables([pq.read_table(p) for p in paths])
    return table.sort_by("cell")
