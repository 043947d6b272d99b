import signal
import tomllib

import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import run_sweep
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


def test_local_and_ray_backends_give_identical_rows_with_simulated_cells(tmp_path, monkeypatch):
    """A local Ray instance; one reachable simulated cell and one out of reach."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
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


def test_an_unknown_backend_is_bad_input_before_any_work(tmp_path):
    with pytest.raises(BadInputError, match="unknown backend"):
        run_sweep(parse_config(tomllib.loads(EXAMPLE)), tmp_path / "out", backend="dask", progress=False)
    assert not (tmp_path / "out").exists()
