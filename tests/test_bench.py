"""`impactqp bench --json` prints rows of {name, unit, median, p99}."""

import json

import pytest

from impactqp.scenarios.cli import main


def test_bench_prediction_rows(capsys):
    """A family's rows come with the floor they are compared with, timed in the same run, and
    their ratio block by block (its median at most its least favourable block, "p99")."""
    assert main(["bench", "--only", "predict.", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    names = {r["name"] for r in rows}
    assert names == {
        "predict.crb.single", "predict.crb.single.fr3", "predict.crb.single.ur5", "predict.crb.batch",
        "predict.crb.batch.cpu", "predict.crb.batch.jobs1",
        "floor.pinocchio.all_terms", "predict.crb.single/floor.pinocchio.all_terms",
    }
    for r in rows:
        assert set(r) == {"name", "unit", "median", "p99"}
        assert r["median"] > 0 and r["p99"] > 0
    by_name = {r["name"]: r for r in rows}
    ratio = by_name["predict.crb.single/floor.pinocchio.all_terms"]
    assert ratio["unit"] == "ratio" and ratio["median"] <= ratio["p99"]


def test_bench_franka_sim_row_comes_from_a_session_through_the_franka_protocol(capsys):
    pytest.importorskip("pylibfranka", reason="pylibfranka is not installed: pip install -e '.[franka]'")
    pytest.importorskip("franky_sim", reason="franky-sim is not installed: pip install -e '.[test]'")
    assert main(["bench", "--only", "loop.franka_sim", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["rows"]
    assert (row["name"], row["unit"]) == ("loop.franka_sim.p99", "us")
    assert 0.0 < row["median"] <= row["p99"] < float("inf")


def test_an_only_prefix_that_selects_no_row_is_bad_input(capsys):
    assert main(["bench", "--only", "nonsense", "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    assert "--only 'nonsense' selects no benchmark row" in captured.err and "predict" in captured.err
