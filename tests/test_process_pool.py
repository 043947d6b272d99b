"""The one process-pool helper (sim/process_pool.py): order, initializer, errors, Ctrl-C."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from concurrent.futures import ProcessPoolExecutor

from impactqp.sim.process_pool import ProcessPool, held_signals, map_in_processes

_SETTING: object = None


def _remember(value: object) -> None:
    global _SETTING
    _SETTING = value


def _with_setting(task: int) -> tuple[int, object]:
    return task, _SETTING


def _square(task: int) -> int:
    return task * task


def _pid(_task: int) -> int:
    return os.getpid()


def _fail_on_three(task: int) -> int:
    if task == 3:
        raise ValueError("task three")
    return task


@pytest.mark.parametrize("jobs", [1, 2, 3])
@pytest.mark.parametrize("count", [0, 1, 7])
def test_results_come_back_in_the_order_of_the_tasks(jobs, count):
    tasks = list(range(count, 0, -1))
    assert map_in_processes(_square, tasks, jobs) == [t * t for t in tasks]


@pytest.mark.parametrize("jobs", [1, 2])
def test_the_initializer_prepares_every_worker_for_every_map(jobs):
    with ProcessPool(jobs, _remember, ("scene",)) as pool:
        first = list(pool.map(_with_setting, range(5)))
        second = list(pool.map(_with_setting, range(5, 9)))
    assert first + second == [(t, "scene") for t in range(9)]


def test_one_job_runs_in_this_process_and_more_run_in_workers():
    assert set(map_in_processes(_pid, range(4), 1)) == {os.getpid()}
    assert os.getpid() not in map_in_processes(_pid, range(4), 2)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_task_raises_here_and_leaves_no_worker_behind(jobs):
    with pytest.raises(ValueError, match="task three"):
        map_in_processes(_fail_on_three, range(6), jobs)
    assert multiprocessing.active_children() == []


@pytest.mark.parametrize("jobs", [0, -1, 1.5, True])
def test_a_pool_needs_a_whole_positive_number_of_jobs(jobs):
    with pytest.raises(ValueError, match="jobs"):
        ProcessPool(jobs)


def test_map_outside_the_with_block_is_refused():
    with pytest.raises(RuntimeError, match="context manager"):
        ProcessPool(1).map(_square, [1])


CTRL_C = textwrap.dedent(
    """
    import os, sys, time
    from impactqp.sim.process_pool import map_in_processes

    def nap(task):
        os.write(1, b"running\\n")  # one write: the two workers' lines never interleave
        time.sleep(600)

    if __name__ == "__main__":
        try:
            map_in_processes(nap, range(4), 2)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(130)
    """
)


def test_ctrl_c_stops_the_workers_at_once_and_only_the_parent_reports_it(tmp_path):
    """SIGINT to the whole process group, as a terminal's Ctrl-C: the parent gets
    KeyboardInterrupt, the running tasks are not waited for and no worker prints a traceback."""
    script = tmp_path / "ctrl_c.py"
    script.write_text(CTRL_C)
    proc = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )
    try:
        # both workers in their task: the signal then finds no process starting up (a worker
        # still unpickling its task when SIGINT arrives is a different, earlier moment)
        assert [proc.stdout.readline() for _ in range(2)] == ["running\n"] * 2
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)  # a hang guard: the tasks would sleep 600 s
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert out.splitlines()[-1] == "interrupted"
    assert "Traceback" not in err


SIGNAL_IN_THE_FORK = textwrap.dedent(
    """
    import os, signal, sys
    from impactqp.sim.process_pool import map_in_processes

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    if __name__ == "__main__":
        signal.signal(signal.SIGNAL_NAME, interrupt)  # as the command line's stop signals
        # the signal comes right after a worker is forked, in the parent's fork callbacks
        os.register_at_fork(after_in_parent=lambda: os.kill(os.getpid(), signal.SIGNAL_NAME))
        try:
            map_in_processes(abs, range(4), 2)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(130)
    """
)


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_stop_signal_while_the_workers_are_forked_is_handled_after_the_fork(tmp_path, sig):
    """A stop signal whose handler raises, arriving while a worker is forked: it waits until the
    workers exist, then ends the map as a KeyboardInterrupt; it is never raised (and swallowed,
    printed as "Exception ignored") inside the interpreter's fork callbacks, where the logging
    module's lock would stay held."""
    script = tmp_path / "fork.py"
    script.write_text(SIGNAL_IN_THE_FORK.replace("SIGNAL_NAME", sig))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 130 and done.stdout == "interrupted\n", done.stderr
    assert done.stderr == ""


@pytest.mark.parametrize("jobs", [1, 2])
def test_progress_counts_every_result_as_it_arrives(jobs):
    """``progress(done, total)`` once per result, done rising 1..n: the callback is told each
    result, in order, before the list is returned."""
    calls = []
    results = map_in_processes(_square, range(5), jobs, lambda done, total: calls.append((done, total)))
    assert results == [t * t for t in range(5)] and calls == [(k, 5) for k in range(1, 6)]


STOP = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGALRM)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


@pytest.mark.parametrize("sig", STOP)
def test_a_held_signal_is_handled_after_the_block_not_inside_it(sig):
    """Inside ``held_signals`` a Python handler does not run (the block finishes); on leaving,
    the handlers are the ones before and the signal reaches its own handler once."""
    calls = []

    def handler(signum, frame):
        calls.append(signum)
        raise KeyboardInterrupt

    before = {s: signal.signal(s, handler) for s in STOP}
    finished = False
    try:
        with pytest.raises(KeyboardInterrupt):
            with held_signals():
                os.kill(os.getpid(), sig)
                os.kill(os.getpid(), sig)
                assert calls == []
                finished = True
        assert finished and calls == [sig]
        assert all(signal.getsignal(s) is handler for s in STOP)
    finally:
        for s, h in before.items():
            signal.signal(s, h)


@pytest.mark.parametrize("failing", [False, True])
def test_a_stop_signal_while_the_workers_are_stopped_comes_after_they_are(monkeypatch, failing):
    """A stop signal at the start of the executor's shutdown (after a normal map or after a
    failed task): it ends the map as a KeyboardInterrupt once the workers are stopped and the
    executor closed, never half-way (workers left, a half-closed executor whose wake-up pipe
    the interpreter's exit writes to: "Exception ignored ... Bad file descriptor")."""
    real_shutdown = ProcessPoolExecutor.shutdown

    def signal_then_shutdown(self, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        return real_shutdown(self, *args, **kwargs)

    monkeypatch.setattr(ProcessPoolExecutor, "shutdown", signal_then_shutdown)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            map_in_processes(_fail_on_three if failing else _square, range(6), 2)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert multiprocessing.active_children() == []
