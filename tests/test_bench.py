"""`impactqp bench --json` prints rows of {name, unit, median, p99}."""

import json

import pytest

from impactqp.scenarios.bench import loop
from impactqp.scenarios.cli import main


def test_bench_prediction_rows(capsys):
    """A family's rows come with the floor they are compared with, timed in the same run."""
    assert main(["bench", "--only", "predict.", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    names = {r["name"] for r in rows}
    assert names == {"predict.crb.single", "predict.crb.batch", "floor.pinocchio.all_terms"}
    for r in rows:
        assert set(r) == {"name", "unit", "median", "p99"}
        assert r["median"] > 0 and r["p99"] > 0


def test_bench_franka_sim_rows_come_from_one_session_through_the_franka_protocol():
    pytest.importorskip("pylibfranka", reason="pylibfranka is not installed: pip install -e '.[franka]'")
    pytest.importorskip("franky_sim", reason="franky-sim is not installed: pip install -e '.[test]'")
    (cycle,) = loop.franka_sim_loop_rows()
    (latency,) = loop.franka_sim_detection_rows()
    assert (cycle["name"], cycle["unit"]) == ("loop.franka_sim.p99", "us")
    assert 0.0 < cycle["median"] <= cycle["p99"] < float("inf")
    assert (latency["name"], latency["unit"]) == ("impact.detection_latency.franka_sim", "ms")
    assert 0.0 <= latency["median"] == latency["p99"] < float("inf")  # detected, never before the contact
