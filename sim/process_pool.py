"""The one process-pool helper of the parallel commands: tasks run on worker processes, results
come back in the order of the tasks.

``ProcessPool(jobs, initializer, initargs)`` is a context manager whose ``map`` may be called
several times on the same workers; ``initializer(*initargs)`` runs once per worker (e.g. to
build a per-worker scene and controller) and, with ``jobs == 1``, once in this process, where
every task then runs: one code path for serial and parallel runs. ``map_in_processes`` is the
one-shot form for a list of tasks.

Interruption: the workers ignore SIGINT, so a Ctrl-C in a terminal (sent to the whole process
group) reaches this process alone. When an exception (``KeyboardInterrupt`` included) leaves the
``with`` block, the pending tasks are cancelled and the workers stopped at once instead of being
waited for; the exception then goes on. Every signal is held (:func:`held_signals`) and blocked
while the workers are forked: a handler that raises (the command line's stop signals) would
otherwise run inside the interpreter's fork callbacks, where the exception is printed and
swallowed and a lock (the logging module's) stays held, or between a worker's start and its
registration in the executor, which then never stops it; the signal waits and is handled once
the workers exist. Stopping
the workers runs under :func:`held_signals`: an interruption in the executor's shutdown leaves
it half-closed, and the interpreter's exit then prints an "Exception ignored" traceback.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any


@contextmanager
def held_signals() -> Iterator[None]:
    """While active (in the main thread; elsewhere it does nothing), a signal with a Python
    handler (the command line's stop signals and the SIGALRM by which it raises a swallowed
    interruption again, Python's Ctrl-C) is recorded instead of handled; on leaving, the handlers
    are put back and each recorded signal is raised again, so an interruption goes on once the
    block is done. For work that must not stop half-way: stopping a pool's workers, starting or
    stopping a Ray cluster, whose processes would otherwise outlive the command."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    previous = {}
    for sig in signal.valid_signals():
        handler = signal.getsignal(sig)
        if callable(handler):
            previous[sig] = signal.signal(sig, lambda signum, frame: came.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for sig in dict.fromkeys(came):
            signal.raise_signal(sig)


def _start_worker(initializer: Callable[..., None] | None, initargs: tuple) -> None:
    """Every worker: leave SIGINT to the parent, which stops the workers itself, and drop the
    command line's SIGTERM and SIGHUP handlers (inherited by a forked worker), then unblock the
    signals (blocked while this worker was forked) and run the caller's initializer."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, signal.valid_signals())
    if initializer is not None:
        initializer(*initargs)


class ProcessPool:
    """``jobs`` worker processes (``jobs == 1``: this process) running tasks in order."""

    def __init__(self, jobs: int, initializer: Callable[..., None] | None = None, initargs: tuple = ()):
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise ValueError(f"a process pool needs a whole number of jobs >= 1, got {jobs!r}")
        self.jobs = jobs
        self.initializer = initializer
        self.initargs = tuple(initargs)
        self._executor: ProcessPoolExecutor | None = None
        self._open = False

    def __enter__(self) -> ProcessPool:
        if self.jobs > 1:
            self._executor = ProcessPoolExecutor(
                self.jobs, initializer=_start_worker, initargs=(self.initializer, self.initargs)
            )
        elif self.initializer is not None:
            self.initializer(*self.initargs)
        self._open = True
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self._open = False
        executor, self._executor = self._executor, None
        if executor is None:
            return
        with held_signals():
            if exc_type is not None:
                # stop the running tasks instead of waiting for them; ProcessPoolExecutor has no
                # public way to do so before Python 3.14
                for worker in list((executor._processes or {}).values()):
                    worker.kill()
            executor.shutdown(wait=True, cancel_futures=True)

    def map(self, function: Callable[[Any], Any], tasks: Iterable) -> Iterator:
        """``function(task)`` for every task, lazily, in the order of ``tasks``. ``function`` must
        be a module-level function (it is pickled to the workers); a task's exception is raised
        here when its result is reached."""
        if not self._open:
            raise RuntimeError("use ProcessPool as a context manager")
        if self._executor is not None:
            # the workers are forked as the tasks are submitted (the module's docstring): the
            # signals are held, as another thread may take a signal whose handler then runs here
            # (in the fork's callbacks, or between a worker's start and its registration, which
            # would leave it unknown to the executor and alive after this process), and blocked,
            # so that a new worker gets none before its own start-up has put its handlers in
            with held_signals():
                previous = signal.pthread_sigmask(signal.SIG_BLOCK, signal.valid_signals())
                try:
                    futures = [self._executor.submit(function, task) for task in tasks]
                finally:
                    signal.pthread_sigmask(signal.SIG_SETMASK, previous)
            # Not ``executor.map``: its iterator cancels the futures left when it is closed, from
            # this thread, while the executor's own thread may be failing them after __exit__
            # killed the workers; a future cancelled in between makes that thread raise
            # InvalidStateError and print a traceback (Python before 3.12). The futures left are
            # cancelled by ``shutdown(cancel_futures=True)``, in the executor's thread.
            return (future.result() for future in futures)
        return map(function, tasks)


def map_in_processes(
    function: Callable[[Any], Any], tasks: Iterable, jobs: int, progress: Callable[[int, int], None] | None = None
) -> list:
    """``[function(task) for task in tasks]`` on at most ``jobs`` worker processes (no more
    than there are tasks; a single task or ``jobs == 1`` runs in this process);
    ``progress(done, total)`` is called as each result arrives, in the order of the tasks."""
    tasks = list(tasks)
    results = []
    with ProcessPool(min(jobs, max(len(tasks), 1))) as pool:
        for result in pool.map(function, tasks):
            results.append(result)
            if progress is not None:
                progress(len(results), len(tasks))
    return results
