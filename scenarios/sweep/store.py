"""Chunked Parquet store of sweep rows, written atomically, with resume.

``DIR/sweep.json`` holds the config of the sweep in ``DIR``; ``DIR/chunk-NNNNNN.parquet`` holds
the rows of cells [NNNNNN * chunk_size, ...). Each chunk is written to a temporary file and moved
into place (``controller.measured.atomic``), so a chunk on disk is complete: resume skips it and
a killed sweep loses or duplicates no row. The Parquet metadata carries the config and the
package version.
"""

from __future__ import annotations

import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic
from impactqp.controller.model.validation import BadInputError

from .config import SweepConfig

CONFIG_FILE = "sweep.json"


def package_version() -> str:
    try:
        return version("impactqp")
    except PackageNotFoundError:
        return "unknown"


def chunk_path(out: Path, chunk: int) -> Path:
    return Path(out) / f"chunk-{chunk:06d}.parquet"


def prepare(out: Path, config: SweepConfig, resume: bool, chunk_size: int) -> None:
    """Claim ``out`` for ``config``; on resume, refuse a directory of another config or chunking."""
    out = Path(out)
    stored = out / CONFIG_FILE
    if stored.exists():
        if not resume:
            raise BadInputError(f"{out} already holds a sweep; pass --resume or choose another --out")
        if json.loads(stored.read_text())["config"] != json.loads(config.canonical_json()):
            raise BadInputError(f"the config differs from the one of the sweep in {out}; cannot --resume")
        if json.loads(stored.read_text())["chunk_size"] != chunk_size:
            raise BadInputError(f"the sweep in {out} was written in chunks of another size; cannot --resume")
        return
    out.mkdir(parents=True, exist_ok=True)
    text = json.dumps(
        {"config": json.loads(config.canonical_json()), "version": package_version(), "chunk_size": chunk_size}
    )
    write_text_atomic(stored, text)


def done_chunks(out: Path, n_chunks: int) -> set[int]:
    return {c for c in range(n_chunks) if chunk_path(out, c).exists()}


def write_chunk(out: Path, chunk: int, rows: list[dict], config: SweepConfig) -> Path:
    table = pa.Table.from_pylist(rows)
    table = table.replace_schema_metadata(
        {"impactqp.sweep.config": config.canonical_json(), "impactqp.version": package_version()}
    )
    return write_atomic(chunk_path(out, chunk), lambda tmp: pq.write_table(table, tmp))


def read_table(out: Path) -> pa.Table:
    """All rows of the sweep in ``out``, sorted by cell."""
    paths = sorted(Path(out).glob("chunk-*.parquet"))
    if not paths:
        raise BadInputError(f"{out} holds no sweep chunk")
    table = pa.concat_tables([pq.read_table(p) for p in paths])
    return table.sort_by("cell")
