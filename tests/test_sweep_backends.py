import tomllib

from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config


def test_one_and_two_worker_processes_give_identical_rows(tmp_path):
    config = parse_config(tomllib.loads(EXAMPLE))
    one = run_sweep(config, tmp_path / "one", jobs=1, chunk_size=4, progress=False)
    two = run_sweep(config, tmp_path / "two", jobs=2, chunk_size=4, progress=False)
    assert one.cells == two.cells == config.cell_count()
    rows = [repr(store.read_table(tmp_path / name).to_pylist()) for name in ("one", "two")]
    assert rows[0] == rows[1]  # exact, NaN == NaN


def test_local_and_ray_backends_give_identical_rows(tmp_path, monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    data = tomllib.loads(EXAMPLE)
    data["grid"].update(size=[0.1, 0.2])
    config = parse_config(data)
    run_sweep(config, tmp_path / "local", jobs=1, chunk_size=2, progress=False, plots=False)
    run_sweep(config, tmp_path / "ray", jobs=2, backend="ray", chunk_size=2, progress=False, plots=False)
    rows = [repr(store.read_table(tmp_path / name).to_pylist()) for name in ("local", "ray")]
    assert rows[0] == rows[1]  # exact, NaN == NaN
