import signal
import tomllib

import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import RAY_STARTS, RayStarter, run_sweep
from impactqp.scenarios.sweep.cells import Simulation
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config


def rows(out):
    return repr(store.read_table(out).to_pylist())  # exact, NaN == NaN


def test_one_and_two_worker_processes_give_identical_rows(tmp_path):
    config = parse_config(tomllib.loads(EXAMPLE))
    one = run_sweep(config, tmp_path / "one", jobs=1, chunk_size=4, progress=False, plots=False)
    two = run_sweep(config, tmp_path / "two", jobs=2, chunk_size=4, progress=False, plots=False)
    assert one.cells == two.cells == config.cell_count()
    assert rows(tmp_path / "one") == rows(tmp_path / "two")


TIMED_OUT = ("The current node timed out during startup. This could happen because some of the raylet failed to "
             "startup or the GCS has become overloaded.")  # Ray's words when its node does not register in 30 s


def ray_init_failing(monkeypatch, failures: int, message: str = TIMED_OUT) -> list:
    """``ray.init`` raising Ray's start-up error ``failures`` times before it runs; its calls."""
    ray = pytest.importorskip("ray")
    init, calls = ray.init, []

    def init_after_failures(*args, **kwargs):
        calls.append(kwargs)
        if len(calls) <= failures:
            raise Exception(message)
        return init(*args, **kwargs)

    monkeypatch.setattr(ray, "init", init_after_failures)
    return calls


def test_local_and_ray_backends_give_identical_rows_with_simulated_cells(tmp_path, monkeypatch):
    """A local Ray instance; one reachable simulated cell and one out of reach. Its first start
    times out (as on a machine whose cores are busy): the second one runs the sweep."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    starts = ray_init_failing(monkeypatch, 1)
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(origin=[0.6, 0.0, 0.7], u=[1.0, 0.0, 0.0], size=[0.9, 0.0], spacing=0.9)
    data["simulate"].update(tolerance=0.1)
    config = parse_config(data)
    local = run_sweep(config, tmp_path / "local", jobs=1, progress=False, plots=False, simulation=Simulation())
    write_chunk, handlers = store.write_chunk, []

    def write_chunk_seeing_the_handler(*args):  # the driver writes each chunk as Ray returns it
        handlers.append(signal.getsignal(signal.SIGTERM))
        return write_chunk(*args)

    def stop(*_):
        raise KeyboardInterrupt

    monkeypatch.setattr(store, "write_chunk", write_chunk_seeing_the_handler)
    previous = signal.signal(signal.SIGTERM, stop)  # the command line's handler
    try:
        ray = run_sweep(
            config, tmp_path / "ray", jobs=2, backend="ray", progress=False, plots=False, simulation=Simulation()
        )
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert handlers and all(h is stop for h in handlers)  # not Ray's own SIGTERM handler (a plain exit)
    assert local.cells == ray.cells == 2 and local.cells_simulated == ray.cells_simulated == 1
    assert rows(tmp_path / "local") == rows(tmp_path / "ray")
    assert len(starts) == 2


def test_a_ray_that_never_starts_is_one_line_and_another_error_is_not_retried(monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    starts = ray_init_failing(monkeypatch, RAY_STARTS)
    with pytest.raises(BadInputError, match=f"Ray did not start in {RAY_STARTS} attempts .*timed out during startup"):
        RayStarter.running(1)
    assert len(starts) == RAY_STARTS
    monkeypatch.undo()
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    starts = ray_init_failing(monkeypatch, 1, "a bug")
    with pytest.raises(Exception, match="^a bug$"):
        RayStarter.running(1)
    assert len(starts) == 1


def test_an_unknown_backend_is_bad_input_before_any_work(tmp_path):
    with pytest.raises(BadInputError, match="unknown backend"):
        run_sweep(parse_config(tomllib.loads(EXAMPLE)), tmp_path / "out", backend="dask", progress=False)
    assert not (tmp_path / "out").exists()
