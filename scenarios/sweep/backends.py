"""Running the sweep's chunks: a local process pool (default)."""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from . import store
from .cells import evaluate_cells
from .config import SweepConfig
from .plots import write_plots

DEFAULT_CHUNK_SIZE = 64


@dataclass(frozen=True)
class SweepSummary:
    out: str
    cells: int
    chunks: int
    chunks_skipped: int
    cells_reachable: int
    wall_time_s: float
    figures: list[str]

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def _chunk_cells(config: SweepConfig, chunk: int, chunk_size: int) -> range:
    return range(chunk * chunk_size, min((chunk + 1) * chunk_size, config.cell_count()))


def _run_chunk(config: SweepConfig, out: str, chunk: int, chunk_size: int) -> int:
    rows = evaluate_cells(config, _chunk_cells(config, chunk, chunk_size))
    store.write_chunk(Path(out), chunk, rows, config)
    return len(rows)


def run_sweep(
    config: SweepConfig,
    out: Path,
    jobs: int = 1,
    resume: bool = False,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    progress: bool = True,
    plots: bool = True,
) -> SweepSummary:
    """Evaluate every cell of ``config`` into ``out`` on a pool of ``jobs`` processes."""
    start = time.perf_counter()
    store.prepare(out, config, resume, chunk_size)
    n_cells = config.cell_count()
    n_chunks = -(-n_cells // chunk_size)
    done = store.done_chunks(out, n_chunks)
    todo = [c for c in range(n_chunks) if c not in done]
    bar = tqdm(total=n_cells, initial=n_cells - sum(len(_chunk_cells(config, c, chunk_size)) for c in todo),
               unit="cell", disable=not progress)
    if jobs <= 1:
        for c in todo:
            bar.update(_run_chunk(config, str(out), c, chunk_size))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_run_chunk, config, str(out), c, chunk_size) for c in todo]
            for future in as_completed(futures):
                bar.update(future.result())
    bar.close()
    table = store.read_table(out)
    figures = write_plots(config, table, Path(out)) if plots else []
    return SweepSummary(
        out=str(out),
        cells=table.num_rows,
        chunks=n_chunks,
        chunks_skipped=len(done),
        cells_reachable=int(sum(table.column("reachable").to_pylist())),
        wall_time_s=time.perf_counter() - start,
        figures=[str(p) for p in figures],
    )
