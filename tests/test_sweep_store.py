import json
import signal
import subprocess
import sys
import time
import tomllib

import pyarrow.parquet as pq
import pytest

from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios.sweep import store
from impactqp.scenarios.sweep.backends import run_sweep
from impactqp.scenarios.sweep.cells import Simulation
from impactqp.scenarios.sweep.config import EXAMPLE, parse_config
from impactqp.sim.plant import PlantParameters

CHUNK = 4  # 168 chunks of the grid below: the kill lands midway even on a loaded machine
DATA = tomllib.loads(EXAMPLE)
DATA["grid"].update(spacing=0.02)
DATA["settings"].update(restitution=[0.0, 0.3])

def test_a_sweep_killed_midway_and_resumed_equals_an_uninterrupted_run(tmp_path):
    config = parse_config(DATA)
    n_chunks = -(-config.cell_count() // CHUNK)
    killed = tmp_path / "killed"
    code = (
        "from impactqp.scenarios.sweep.backends import run_sweep\n"
        "from impactqp.scenarios.sweep.config import parse_config\n"
        f"run_sweep(parse_config({DATA!r}), {str(killed)!r}, chunk_size={CHUNK}, progress=False, plots=False)\n"
    )
    process = subprocess.Popen([sys.executable, "-c", code])
    while not list(killed.glob("chunk-*.parquet")) and process.poll() is None:  # however slow the machine
        time.sleep(0.005)
    process.send_signal(signal.SIGKILL)
    process.wait()
    written = len(list(killed.glob("chunk-*.parquet")))
    assert 1 <= written < n_chunks  # killed midway
    summary = run_sweep(config, killed, resume=True, chunk_size=CHUNK, progress=False, plots=False)
    assert summary.chunks_skipped == written
    whole = tmp_path / "whole"
    run_sweep(config, whole, chunk_size=CHUNK, progress=False, plots=False)
    resumed, uninterrupted = store.read_table(killed), store.read_table(whole)
    assert resumed.column("cell").to_pylist() == list(range(config.cell_count()))
    assert repr(resumed.to_pylist()) == repr(uninterrupted.to_pylist())  # exact, NaN == NaN
    assert not list(killed.glob(".*"))  # resume removed a temporary chunk the kill left behind


def test_resume_refuses_another_config_and_a_second_run_needs_resume(tmp_path):
    small = dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1))
    config = parse_config(small)
    run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    with pytest.raises(BadInputError, match="--resume"):
        run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    other = parse_config(dict(small, settings=dict(small["settings"], restitution=[0.1])))
    with pytest.raises(BadInputError, match="config differs"):
        run_sweep(other, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False)


def test_resume_refuses_another_simulate_flag_or_plant(tmp_path):
    """Out of reach: the simulated cells are recorded unreachable, so no trial runs."""
    config = parse_config(dict(DATA, grid=dict(DATA["grid"], origin=[1.5, 0.0, 0.5], size=[0.1, 0.0], spacing=0.1)))
    heavy = Simulation(PlantParameters(payload_mass=1.0))
    summary = run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False, simulation=heavy)
    assert summary.cells == config.cell_count() and summary.cells_simulated == 0
    for other, message in (
        (Simulation(), "the --plant file differs"),
        (Simulation(PlantParameters(payload_mass=2.0)), "the --plant file differs"),
        (None, "--simulate differs"),
    ):
        with pytest.raises(BadInputError, match=message):
            run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False, simulation=other)
    again = run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False, simulation=heavy)
    assert again.chunks_skipped == again.chunks


def test_chunks_carry_the_config_and_the_package_version(tmp_path):
    config = parse_config(dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1)))
    run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    metadata = pq.read_schema(store.chunk_path(tmp_path, 0)).metadata
    identity = json.loads(metadata[b"impactqp.sweep"])
    assert identity == {"config": json.loads(config.canonical_json()), "simulate": False, "plant": None}
    assert metadata[b"impactqp.version"].decode() == store.package_version()


@pytest.mark.parametrize("simulate", [False, True])
def test_the_room_estimate_bounds_the_chunks_written(tmp_path, simulate):
    """``output_bytes`` is at least the size of the chunk files a sweep writes (the rows at their
    uncompressed size): the check before the work asks for no less than the work needs.
    Simulated, the cells are out of reach (recorded unreachable, no trial runs) but carry the
    simulated columns."""
    origin = [1.5, 0.0, 0.5] if simulate else DATA["grid"]["origin"]
    config = parse_config(dict(DATA, grid=dict(DATA["grid"], origin=origin, size=[0.1, 0.1], spacing=0.05)))
    simulation = Simulation() if simulate else None
    summary = run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False, simulation=simulation)
    written = sum(path.stat().st_size for path in tmp_path.glob("chunk-*.parquet"))
    assert 0 < written <= store.output_bytes(config, simulation, summary.cells, summary.chunks)


def test_a_disk_without_room_is_refused_before_any_cell(tmp_path, monkeypatch):
    """Less free space than the margin times the estimate: one BadInputError naming the folder
    and the estimate, and nothing written (the folder is not even made); on resume, only the
    chunks still to write count."""
    import shutil

    from impactqp.controller.measured import dataset_writer

    config = parse_config(dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1)))
    out = tmp_path / "sweep"
    estimate = store.output_bytes(config, None, config.cell_count(), -(-config.cell_count() // CHUNK))
    usage = shutil.disk_usage(tmp_path)._replace(free=int(estimate))  # less than the margin asks
    with monkeypatch.context() as patch:
        patch.setattr(dataset_writer.shutil, "disk_usage", lambda path: usage)
        with pytest.raises(BadInputError, match=rf"{out}: the rows of {config.cell_count()} cells need about .* MB are free"):
            run_sweep(config, out, chunk_size=CHUNK, progress=False, plots=False)
    assert not out.exists()
    run_sweep(config, out, chunk_size=CHUNK, progress=False, plots=False)
    nothing_left = shutil.disk_usage(tmp_path)._replace(free=0)
    monkeypatch.setattr(dataset_writer.shutil, "disk_usage", lambda path: nothing_left)
    again = run_sweep(config, out, resume=True, chunk_size=CHUNK, progress=False, plots=False)  # nothing to write
    assert again.chunks_skipped == again.chunks


def test_a_chunk_that_is_not_a_parquet_file_of_the_sweep_is_refused_naming_it(tmp_path):
    """Reading the rows (``read_table``) and checking a chunk on resume (``check_chunk``): a
    truncated chunk is not a Parquet file; a Parquet file without the sweep's identity, or with
    another's, holds the rows of another sweep; the sweep's own chunk passes."""
    import pyarrow as pa

    config = parse_config(dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1)))
    run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    ours, chunk = store.identity(config, None), store.chunk_path(tmp_path, 0)
    store.check_chunk(chunk, ours)
    with pytest.raises(BadInputError) as refused:
        store.check_chunk(chunk, store.identity(config, Simulation()))
    assert str(refused.value) == (f"the sweep chunk {chunk} holds the rows of another sweep (its config, "
                                  "--simulate or --plant); remove it and --resume to write it again")
    pq.write_table(pa.table({"cell": [0]}), chunk)
    with pytest.raises(BadInputError, match="holds the rows of another sweep"):
        store.check_chunk(chunk, ours)
    chunk.write_bytes(chunk.read_bytes()[:-8])  # no footer
    not_parquet = f"the sweep chunk {chunk} is not a Parquet file; remove it and --resume to write it again"
    for refuse in (lambda: store.check_chunk(chunk, ours), lambda: store.read_table(tmp_path)):
        with pytest.raises(BadInputError) as refused:
            refuse()
        assert str(refused.value) == not_parquet


@pytest.mark.parametrize("record, message", [
    (bytes(range(128, 256)), "is not a UTF-8 text file"),
    (b'{"config": ', "is not valid JSON"),
])
def test_resume_refuses_a_spoilt_sweep_record_naming_it(tmp_path, record, message):
    config = parse_config(dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1)))
    run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    (tmp_path / store.CONFIG_FILE).write_bytes(record)
    with pytest.raises(BadInputError, match=f"^the sweep record {tmp_path / store.CONFIG_FILE} {message}"):
        run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False)


def test_resume_checks_the_chunks_without_a_record_and_keeps_a_folder_named_like_a_temporary_chunk(tmp_path):
    """A chunk on disk is skipped on resume, so it is checked even when ``sweep.json`` is gone
    (nothing is written then); a folder named like a killed chunk's temporary file is not one and
    stays, while the temporary file itself is removed."""
    config = parse_config(dict(DATA, grid=dict(DATA["grid"], size=[0.1, 0.0], spacing=0.1)))
    run_sweep(config, tmp_path, chunk_size=CHUNK, progress=False, plots=False)
    chunk = store.chunk_path(tmp_path, 0)
    whole = chunk.read_bytes()
    (tmp_path / store.CONFIG_FILE).unlink()
    chunk.write_bytes(whole[:100])
    with pytest.raises(BadInputError, match=f"^the sweep chunk {chunk} is not a Parquet file"):
        run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False)
    assert not (tmp_path / store.CONFIG_FILE).exists()
    chunk.write_bytes(whole)
    (tmp_path / ".chunk-000000.parquet.0123456789abcdef.parquet").write_bytes(whole[:100])
    (tmp_path / ".chunk-folder").mkdir()
    summary = run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False)
    assert summary.chunks_skipped == summary.chunks == 1  # written again: sweep.json, the record the next needs
    run_sweep(config, tmp_path, resume=True, chunk_size=CHUNK, progress=False, plots=False)
    assert [p.name for p in tmp_path.glob(".*")] == [".chunk-folder"]
