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
from impactqp.controller.measured.dataset_writer import check_room
from impactqp.controller.model.validation import BadInputError, counted

from .cells import Simulation, evaluate_cells
from .config import SweepConfig

CONFIG_FILE = "sweep.json"
CHUNK_FOOTER_BYTES = 16_384
"""Bytes of a chunk file beyond its rows and the sweep's identity: Parquet's magic numbers and
footer (the schema and each column chunk's statistics, a few hundred bytes per column)."""
SIMULATED_ROW_BYTES = 48
"""Bytes a row of ``--simulate`` adds: ``simulated_max_speed``, ``qp_limited_speed`` and
``simulated_impacts`` (8 bytes each) and ``simulated_status`` (at most 11 characters and a 4-byte
offset)."""


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


def output_bytes(config: SweepConfig, simulation: Simulation | None, cells: int, chunks: int) -> float:
    """An estimate of the size of ``cells`` rows of ``config`` in ``chunks`` chunk files: the first
    cell's closed-form row, evaluated, at its Arrow size (the data uncompressed; Parquet stores
    it in fewer bytes), plus ``SIMULATED_ROW_BYTES`` per row with ``--simulate``, plus per chunk
    the sweep's identity (its metadata) and ``CHUNK_FOOTER_BYTES``. The figures are not counted."""
    row = pa.table(evaluate_cells(config, range(0, 1))).nbytes + (SIMULATED_ROW_BYTES if simulation is not None else 0)
    per_chunk = len(json.dumps(identity(config, simulation))) + CHUNK_FOOTER_BYTES
    return float(cells * row + chunks * per_chunk)


def check_output_room(out: Path, config: SweepConfig, simulation: Simulation | None, todo: dict[int, int]) -> None:
    """Refuse (one line, before any chunk is evaluated) an ``out`` that cannot be written or has no
    room for the chunks still to write, ``todo`` (chunk: its number of cells): ``check_room`` of
    ``output_bytes``."""
    cells = sum(todo.values())
    check_room(out, output_bytes(config, simulation, cells, len(todo)), f"the rows of {counted(cells, 'cell')}")


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
