"""``impactqp sweep``: --example is a runnable config; bad input is one line and exit code 2."""

import json

import pyarrow.parquet as pq
import pytest

from impactqp.scenarios.cli import main


def test_the_example_config_runs_and_writes_one_row_per_cell(tmp_path, capsys):
    assert main(["sweep", "--example"]) == 0
    config = tmp_path / "sweep.toml"
    config.write_text(capsys.readouterr().out.replace("size = [0.4, 0.3]", "size = [0.1, 0.1]"))
    out = tmp_path / "out"
    assert main(["sweep", str(config), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cells"] == 4
    assert sum(pq.read_table(p).num_rows for p in out.glob("chunk-*.parquet")) == 4


@pytest.mark.parametrize(
    "text, message",
    [
        ("[grid\n", "malformed"),
        ("[grid]\nfoo = 1\n", "unknown key grid.foo"),
        ("", "needs a [grid] table"),
    ],
)
def test_bad_config_is_one_line_and_exit_code_2_before_any_work(tmp_path, capsys, text, message):
    config = tmp_path / "bad.toml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main(["sweep", str(config), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_spacing_zero_is_refused(tmp_path, capsys):
    assert main(["sweep", "--example"]) == 0
    config = tmp_path / "sweep.toml"
    config.write_text(capsys.readouterr().out.replace("spacing = 0.1", "spacing = 0.0"))
    assert main(["sweep", str(config), "--out", str(tmp_path / "out")]) == 2
    assert "grid.spacing must be > 0" in capsys.readouterr().err
