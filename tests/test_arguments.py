"""Command-line arguments shared by the commands (``scenarios.cli.arguments``): input and output
paths, ``--robot``/``--tool``, the progress callback; each bad one is one line with exit code 2."""

import pytest

from cli_checks import one_line_bad_input, run


def test_plant_that_is_a_directory_is_bad_input(capsys, tmp_path):
    code, out, err = run(capsys, "max-speed", "--posture", "elbow_up", "--plant", str(tmp_path))
    one_line_bad_input(code, out, err, "is a directory, not a file")


def test_output_directory_that_is_a_file_is_bad_input(capsys, tmp_path):
    existing = tmp_path / "taken"
    existing.write_text("keep me")
    code, out, err = run(capsys, "campaign", "--out", str(existing), "--speeds", "0.1", "--tangential", "none")
    one_line_bad_input(code, out, err, "not a directory")
    assert existing.read_text() == "keep me"


@pytest.mark.parametrize(
    "command",
    [
        ("campaign", "--out", "", "--speeds", "0.1", "--tangential", "none"),
        ("campaign", "--out", "  ", "--speeds", "0.1", "--tangential", "none"),
        ("dataset", "generate", "", "--speeds", "0.1"),
        ("simulate", "--posture", "elbow_up", "--speed", "0.1", "--video", ""),
        ("demo", "--out", ""),
    ],
    ids=["campaign", "campaign-blank", "generate", "video", "demo"],
)
def test_an_empty_output_path_is_bad_input_and_nothing_lands_in_the_working_directory(
    capsys, tmp_path, monkeypatch, command
):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *command)
    one_line_bad_input(code, out, err, "is empty")
    assert list(tmp_path.iterdir()) == []


def test_output_under_a_file_is_bad_input(capsys, tmp_path):
    existing = tmp_path / "file"
    existing.write_text("x")
    code, out, err = run(capsys, "dataset", "generate", str(existing / "sub"), "--speeds", "0.1")
    one_line_bad_input(code, out, err, "not a directory")


@pytest.mark.parametrize("args, message", [
    (["--robot", "kuka"], "unknown robot 'kuka'; choose from panda, fr3, ur5, g1"),
    (["--tool", "hammer"], "unknown tool 'hammer'"),
    (["--tool", "absent.toml"], "the tool file absent.toml does not exist"),
])
def test_a_bad_robot_or_tool_is_one_line_and_exit_2(capsys, args, message):
    code, out, err = run(capsys, "postures", *args)
    assert code == 2 and out == "" and message in err and len(err.strip().splitlines()) == 1


def test_the_progress_callback_drives_a_tqdm_bar():
    """``bar_progress``: the demo's stage-2 bar follows generate_dataset's progress(done, total)."""
    import io

    from tqdm import tqdm

    from impactqp.scenarios.cli.arguments import bar_progress

    with tqdm(file=io.StringIO()) as bar:
        progress = bar_progress(bar)
        for done in (1, 2, 6):
            progress(done, 6)
            assert (bar.n, bar.total) == (done, 6)
