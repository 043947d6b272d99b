"""Running the sweep's chunks: a local process pool (default) or a Ray cluster.

Workers only evaluate cells and return rows; the driver writes every chunk, so a Ray cluster
needs no shared file system and both backends write the same files.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from impactqp.controller.model.validation import BadInputError
from impactqp.sim.process_pool import ProcessPool, held_signals

from . import store
from .cells import Simulation, evaluate_cells
from .config import SweepConfig
from .plots import write_plots

CLOSED_FORM_CHUNK_SIZE = 1024
"""Cells per chunk of a closed-form sweep: one batch of the vectorised inverse kinematics."""
SIMULATED_CHUNK_SIZE = 1
"""Cells per chunk with ``--simulate``: a simulated cell takes seconds, so each is its own task."""


def default_chunk_size(simulation: Simulation | None) -> int:
    return CLOSED_FORM_CHUNK_SIZE if simulation is None else SIMULATED_CHUNK_SIZE


@dataclass(frozen=True)
class SweepSummary:
    out: str
    cells: int
    chunks: int
    chunks_skipped: int
    cells_reachable: int
    cells_simulated: int  # with simulated_status "simulated"; 0 without --simulate
    wall_time_s: float
    figures: list[str]

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def _chunk_cells(config: SweepConfig, chunk: int, chunk_size: int) -> range:
    return range(chunk * chunk_size, min((chunk + 1) * chunk_size, config.cell_count()))


BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class ChunkTask:
    """One chunk of cells to evaluate on a worker."""

    config: SweepConfig
    simulation: Simulation | None
    chunk: int
    chunk_size: int


def _evaluate_chunk(task: ChunkTask) -> tuple[int, dict]:
    cells = _chunk_cells(task.config, task.chunk, task.chunk_size)
    return task.chunk, evaluate_cells(task.config, cells, task.simulation)


def _evaluate_chunk_parts(config: SweepConfig, simulation: Simulation | None, chunk: int, chunk_size: int):
    """``_evaluate_chunk`` for Ray, which resolves object references passed as arguments only."""
    return _evaluate_chunk(ChunkTask(config, simulation, chunk, chunk_size))


def _local(config: SweepConfig, simulation: Simulation | None, todo: list[int], chunk_size: int, jobs: int):
    """Yield (chunk, columns) in chunk order, on the project's process pool of ``jobs`` processes
    (in-process for 1); each chunk is written as soon as it and the ones before it are done."""
    with ProcessPool(max(1, min(jobs, len(todo)))) as pool:
        yield from pool.map(_evaluate_chunk, [ChunkTask(config, simulation, c, chunk_size) for c in todo])


def _ray(config: SweepConfig, simulation: Simulation | None, todo: list[int], chunk_size: int, jobs: int):
    """Yield (chunk, columns) as they finish on Ray: the cluster at RAY_ADDRESS, else a local Ray.
    A Ray this function started is shut down however the function ends (a stop signal
    included), never half-way: none of its processes outlives the command."""
    import ray  # optional dependency (the ray extra): loaded only for this backend

    starter = None if ray.is_initialized() else RayStarter.running(jobs)
    try:
        remote = ray.remote(num_cpus=1)(_evaluate_chunk_parts)
        config_ref, simulation_ref = ray.put(config), ray.put(simulation)
        pending = [remote.remote(config_ref, simulation_ref, c, chunk_size) for c in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if starter is not None:
            starter.stop()


RAY_STARTS = 3
"""Attempts at starting a local Ray whose node times out during its start (``RayStarter.running``)."""
RAY_START_TIMEOUT = "timed out during startup"
"""Ray's words when its node did not register within its fixed wait (30 s): an overloaded machine."""


class RayStarter:
    """A Ray of this process, started and stopped whole: ``ray.init`` runs on a thread of its own,
    waited for to its end even when a stop signal comes meanwhile (the signal goes on after it),
    and the thread lives until ``stop`` has shut Ray down (Ray's processes die with the thread
    that started them). Off the main thread, ``ray.init`` also leaves the command line's SIGTERM
    handler in place (in the main thread it puts in its own, ``sys.exit``, which would turn a
    stop signal into a plain exit code 15)."""

    @classmethod
    def running(cls, jobs: int) -> RayStarter:
        """A started Ray of ``jobs`` CPUs. Ray gives its node a fixed 30 s to register, which a
        machine whose cores are busy can overrun; such a start is stopped (its processes end
        with its thread) and tried again, up to ``RAY_STARTS`` times, then one line of error."""
        for attempt in range(1, RAY_STARTS + 1):
            starter = cls(jobs)
            try:
                starter.start()
            except BaseException as error:
                starter.stop()
                if not isinstance(error, Exception) or RAY_START_TIMEOUT not in str(error):
                    raise
                if attempt == RAY_STARTS:
                    raise BadInputError(f"Ray did not start in {RAY_STARTS} attempts ({error}); "
                                        "the machine may be overloaded") from None
                continue
            return starter

    def __init__(self, jobs: int):
        address = os.environ.get("RAY_ADDRESS")
        options = {"address": address} if address else {"num_cpus": jobs, "include_dashboard": False}
        # Ray's notes (the SIGTERM handler it did not set, its start) are no news to the user
        self.options = options | {"log_to_driver": False, "logging_level": logging.ERROR}
        self.started, self.stopped = threading.Event(), threading.Event()
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="ray-init", daemon=True)

    def _run(self) -> None:
        import ray

        try:
            ray.init(**self.options)
        except BaseException as error:  # noqa: BLE001 - handed to the main thread
            self.error = error
        self.started.set()
        self.stopped.wait()

    def start(self) -> None:
        self.thread.start()
        try:
            self.started.wait()
        finally:
            with held_signals():
                self.started.wait()
        if self.error is not None:
            raise self.error

    def stop(self) -> None:
        """Shut Ray down (whole, whatever signal comes meanwhile) and end the thread."""
        import ray

        if self.thread.ident is None:  # never started
            return
        with held_signals():
            self.started.wait()
            ray.shutdown()
            self.stopped.set()
            self.thread.join()


@dataclass(frozen=True)
class SweepRun:
    """How ``run_sweep`` runs: ``jobs`` workers of ``backend``, resuming the chunks already in
    the output directory (``resume``), in chunks of ``chunk_size`` cells (None: by default
    ``default_chunk_size``), with a progress bar and heat maps or not, and ``simulation`` for
    ``--simulate`` (None: closed forms only)."""

    jobs: int = 1
    backend: str = "local"
    resume: bool = False
    chunk_size: int | None = None
    progress: bool = True
    plots: bool = True
    simulation: Simulation | None = None


def run_sweep(config: SweepConfig, out: Path, **options) -> SweepSummary:
    """Evaluate every cell of ``config`` into ``out`` as the ``options`` (the fields of
    :class:`SweepRun`) say. The progress bar (stderr) shows cells done, cells/s and the time left."""
    run = SweepRun(**options)
    jobs, backend, resume, simulation = run.jobs, run.backend, run.resume, run.simulation
    chunk_size, progress, plots = run.chunk_size, run.progress, run.plots
    if chunk_size is None:
        chunk_size = default_chunk_size(simulation)
    if backend not in BACKENDS:
        raise BadInputError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
    if backend == "ray":
        try:
            import ray  # noqa: F401  # optional dependency: checked before any work
        except ImportError:
            raise BadInputError("the ray backend needs Ray: pip install -e '.[ray]'") from None
    start = time.perf_counter()
    n_cells = config.cell_count()
    n_chunks = -(-n_cells // chunk_size)
    if resume:  # the stored sweep is checked first, then the room for what is left of it
        store.prepare(out, config, simulation, resume, chunk_size)
    done = store.done_chunks(out, n_chunks) if resume else set()
    todo = [c for c in range(n_chunks) if c not in done]
    store.check_output_room(out, config, simulation, {c: len(_chunk_cells(config, c, chunk_size)) for c in todo})
    if not resume:
        store.prepare(out, config, simulation, resume, chunk_size)
    sweep_identity = store.identity(config, simulation)
    bar = tqdm(total=n_cells, initial=n_cells - sum(len(_chunk_cells(config, c, chunk_size)) for c in todo),
               unit="cell", disable=None if progress else True)
    evaluate = _ray if backend == "ray" else _local
    for chunk, columns in evaluate(config, simulation, todo, chunk_size, jobs):
        store.write_chunk(Path(out), chunk, columns, sweep_identity)
        bar.update(len(columns["cell"]))
    bar.close()
    table = store.read_table(out)
    figures = write_plots(config, table, Path(out)) if plots else []
    return SweepSummary(
        out=str(out),
        cells=table.num_rows,
        chunks=n_chunks,
        chunks_skipped=len(done),
        cells_reachable=int(sum(table.column("reachable").to_pylist())),
        cells_simulated=(
            table.column("simulated_status").to_pylist().count("simulated") if simulation is not None else 0
        ),
        wall_time_s=time.perf_counter() - start,
        figures=[str(p) for p in figures],
    )
