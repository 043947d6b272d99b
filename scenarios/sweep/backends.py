"""Running the sweep's chunks: a local process pool (default) or a Ray cluster.

Workers only evaluate cells and return rows; the driver writes every chunk, so a Ray cluster
needs no shared file system and both backends write the same files.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from impactqp.controller.model.validation import BadInputError

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


BACKENDS = ("local", "ray")


def _evaluate_chunk(config: SweepConfig, chunk: int, chunk_size: int) -> tuple[int, list[dict]]:
    return chunk, evaluate_cells(config, _chunk_cells(config, chunk, chunk_size))


def _local(config: SweepConfig, todo: list[int], chunk_size: int, jobs: int):
    """Yield (chunk, rows) as they finish, on a pool of ``jobs`` processes (in-process for 1)."""
    if jobs <= 1:
        for c in todo:
            yield _evaluate_chunk(config, c, chunk_size)
        return
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(_evaluate_chunk, config, c, chunk_size) for c in todo]
        for future in as_completed(futures):
            yield future.result()


def _ray(config: SweepConfig, todo: list[int], chunk_size: int, jobs: int):
    """Yield (chunk, rows) as they finish on Ray: the cluster at RAY_ADDRESS, else a local Ray."""
    import ray

    started = not ray.is_initialized()
    if started:
        if os.environ.get("RAY_ADDRESS"):
            ray.init(address=os.environ["RAY_ADDRESS"], log_to_driver=False)
        else:
            ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(num_cpus=1)(_evaluate_chunk)
        config_ref = ray.put(config)
        pending = [remote.remote(config_ref, c, chunk_size) for c in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started:
            ray.shutdown()


def run_sweep(
    config: SweepConfig,
    out: Path,
    jobs: int = 1,
    backend: str = "local",
    resume: bool = False,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    progress: bool = True,
    plots: bool = True,
) -> SweepSummary:
    """Evaluate every cell of ``config`` into ``out`` with ``jobs`` workers of ``backend``."""
    if backend not in BACKENDS:
        raise BadInputError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise BadInputError("the ray backend needs Ray: pip install -e '.[ray]'") from None
    start = time.perf_counter()
    store.prepare(out, config, resume, chunk_size)
    n_cells = config.cell_count()
    n_chunks = -(-n_cells // chunk_size)
    done = store.done_chunks(out, n_chunks)
    todo = [c for c in range(n_chunks) if c not in done]
    bar = tqdm(total=n_cells, initial=n_cells - sum(len(_chunk_cells(config, c, chunk_size)) for c in todo),
               unit="cell", disable=not progress)
    run = _ray if backend == "ray" else _local
    for chunk, rows in run(config, todo, chunk_size, jobs):
        store.write_chunk(Path(out), chunk, rows, config)
        bar.update(len(rows))
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
