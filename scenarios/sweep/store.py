"""Chunked Parquet store of sweep rows, written atomically, with resume.

``DIR/sweep.json`` holds the identity of the sweep in ``DIR`` (its config, whether cells are
simulated and the plant of ``--plant``, :func:`identity`), the package version and the chunk size;
``DIR/chunk-NNNNNN.parquet`` holds the rows of cells [NNNNNN * chunk_size, ...). Each chunk is
written to a temporary file and moved into place (``controller.measured.atomic``), so a chunk on
disk is complete: resume skips it (and removes the temporary file a kill may leave) and a killed
sweep loses or duplicates no row. The Parquet metadata carries the identity and the package
version. Resume first checks every chunk on disk (``check_chunk``): one that is not a regular
file, not a Parquet file or the rows of another sweep is refused in one line naming it.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic
from impactqp.controller.measured.dataset_writer import check_room
from impactqp.controller.model.files import read_mapping, regular_file
from impactqp.controller.model.validation import BadInputError, counted

from .cells import Simulation, evaluate_cells
from .config import SweepConfig

CONFIG_FILE = "sweep.json"
CHUNK = "the sweep chunk"
"""What a chunk file is called in a message."""
IDENTITY_KEY = b"impactqp.sweep"
"""The key of the sweep's identity in a chunk's Parquet metadata."""
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
    """Claim ``out`` for the sweep; on resume, refuse a directory of another sweep or chunking, or
    holding a chunk that is not one of this sweep's (``check_chunk``)."""
    out = Path(out)
    stored = out / CONFIG_FILE
    ours = identity(config, simulation)
    recorded = stored.exists()
    if recorded:
        if not resume:
            raise BadInputError(f"{out} already holds a sweep; pass --resume or choose another --out")
        theirs = read_mapping(stored, "the sweep record", "json")
        for key, what in (("config", "the config"), ("simulate", "--simulate"), ("plant", "the --plant file")):
            if theirs.get(key) != ours[key]:
                raise BadInputError(f"{what} differs from the one of the sweep in {out}; cannot --resume")
        if theirs.get("chunk_size") != chunk_size:
            raise BadInputError(f"the sweep in {out} was written in chunks of another size; cannot --resume")
    if resume:  # the chunks on disk are skipped: each must be one of this sweep's
        for path in sorted(out.glob("chunk-*.parquet")):
            check_chunk(path, ours)
    if recorded:
        for leftover in out.glob(".chunk-*"):  # the temporary file of a chunk being written when killed
            if not leftover.is_dir():  # a folder of that name is not ours
                leftover.unlink()
        return
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(stored, json.dumps(ours | {"version": package_version(), "chunk_size": chunk_size}))


def _not_a_chunk(path: Path, what: str) -> BadInputError:
    return BadInputError(f"{CHUNK} {path} {what}; remove it and --resume to write it again")


def check_chunk(path: Path, sweep_identity: dict) -> None:
    """Refuse (one line naming it) the chunk file ``path`` when it is not a regular file (never
    opened then: a FIFO would block), not a Parquet file (a truncated chunk included: its footer is
    read, not its rows), or not the rows of the sweep ``sweep_identity`` (its metadata)."""
    regular_file(path, CHUNK)
    try:
        metadata = pq.read_schema(path).metadata or {}
    except (pa.ArrowException, OSError):
        raise _not_a_chunk(path, "is not a Parquet file") from None
    try:
        theirs = json.loads(metadata.get(IDENTITY_KEY, b"null"))
    except ValueError:
        theirs = None
    if theirs != json.loads(json.dumps(sweep_identity)):
        raise _not_a_chunk(path, "holds the rows of another sweep (its config, --simulate or --plant)")


def done_chunks(out: Path, n_chunks: int) -> set[int]:
    return {c for c in range(n_chunks) if chunk_path(out, c).exists()}


def write_chunk(out: Path, chunk: int, columns: dict, sweep_identity: dict) -> Path:
    """Write the rows ``columns`` (name -> values) of ``chunk`` atomically."""
    table = pa.table(columns)
    table = table.replace_schema_metadata(
        {IDENTITY_KEY: json.dumps(sweep_identity), "impactqp.version": package_version()}
    )
    return write_atomic(chunk_path(out, chunk), lambda tmp: pq.write_table(table, tmp))


def read_table(out: Path) -> pa.Table:
    """All rows of the sweep in ``out``, sorted by cell; a chunk that is not a regular Parquet
    file is refused naming it."""
    paths = sorted(Path(out).glob("chunk-*.parquet"))
    if not paths:
        raise BadInputError(f"{out} holds no sweep chunk")
    table = pa.concat_tables([_read_chunk(p) for p in paths])
    return table.sort_by("cell")


def _read_chunk(path: Path) -> pa.Table:
    regular_file(path, CHUNK)
    try:
        return pq.read_table(path)
    except (pa.ArrowException, OSError):
        raise _not_a_chunk(path, "is not a Parquet file") from None
