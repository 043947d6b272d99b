"""`impactqp bench --json` prints rows of {name, unit, median, p99}."""

import json

from impactqp.scenarios.cli import main


def test_bench_prediction_rows(capsys):
    """A family's rows come with the floor they are compared with, timed in the same run."""
    assert main(["bench", "--only", "predict.", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    names = {r["name"] for r in rows}
    assert names == {"predict.crb.single", "predict.crb.single.fr3", "predict.crb.batch", "floor.pinocchio.all_terms"}
    for r in rows:
        assert set(r) == {"name", "unit", "median", "p99"}
        assert r["median"] > 0 and r["p99"] > 0
