"""Docs that run: every fenced ``python`` block of the README and of ``docs/*.md`` runs in a fresh
interpreter (each block defines what it uses; ``sh``, ``toml`` and ``text`` blocks are not run)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(line of the opening fence, code) of every fenced ``python`` block of a Markdown text."""
    return [(text.count("\n", 0, m.start()) + 1, m.group(1)) for m in FENCE.finditer(text)]


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


BLOCKS = [
    (f"{path.relative_to(ROOT)}:{line}", code)
    for path in documents()
    for line, code in python_blocks(path.read_text(encoding="utf-8"))
]


def test_blocks_are_found_with_their_line_and_only_python_ones():
    text = "intro\n```sh\nmake test\n```\n\n```python\nx = 1\n```\n```python  \ny = 2\nprint(y)\n```\n"
    assert python_blocks(text) == [(6, "x = 1\n"), (9, "y = 2\nprint(y)\n")]


def test_the_readme_has_python_examples():
    assert any(name.startswith("README.md:") for name, _ in BLOCKS)


@pytest.mark.parametrize("code", [code for _, code in BLOCKS], ids=[name for name, _ in BLOCKS])
def test_every_python_block_runs(code, tmp_path):
    # a fresh interpreter per block, in an empty directory (a block's files stay out of the checkout)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr


TOML_FENCE = re.compile(r"^```toml[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
TOML_BLOCKS = [
    (f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}", m.group(1))
    for path in documents()
    for text in [path.read_text(encoding="utf-8")]
    for m in TOML_FENCE.finditer(text)
]


@pytest.mark.parametrize("code", [code for _, code in TOML_BLOCKS], ids=[name for name, _ in TOML_BLOCKS])
def test_every_toml_block_parses_and_a_robot_file_loads(code, tmp_path):
    """Every ``toml`` block is valid TOML; a robot description (a block with a ``base``) loads
    with the UR5's URDF in place of the file it names."""
    import shutil
    import tomllib

    data = tomllib.loads(code)
    if "base" not in data:
        return
    from impactqp.controller.model.robot_description import ROBOTS, robot_description

    shutil.copy(ROBOTS["ur5"].urdf_path(), tmp_path / data["urdf"])
    path = tmp_path / "robot.toml"
    path.write_text(code)
    robot = robot_description(path)
    assert robot.name == data["name"] and set(robot.postures) == set(data.get("postures", {}))


SH_FENCE = re.compile(r"^```sh[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
DATA_SUFFIXES = (".toml", ".json", ".yaml", ".yml")


def test_the_example_files_load_and_every_input_file_a_shell_block_names_ships():
    """``docs/examples`` holds the README's own tool and robot files, which load through the real
    readers; every ``.toml``/``.json``/``.yaml`` input a ``sh`` block of the docs names with a path
    ships in the repository (an output file, after ``--out``/``--log``/``--save-plant``, need not)."""
    from impactqp.controller.model.robot_description import robot_description
    from impactqp.controller.model.tool_description import tool_description

    hammer = tool_description(ROOT / "docs" / "examples" / "my_hammer.toml")
    assert hammer.name == "my_hammer" and hammer.mass == 0.5 and hammer.replaces_hand
    arm = robot_description(ROOT / "docs" / "examples" / "my_arm.toml")
    assert arm.name == "my_arm" and arm.default_posture == "ready" and len(arm.joints) == 6
    named = []
    for path in documents():
        for block in SH_FENCE.findall(path.read_text(encoding="utf-8")):
            for line in block.splitlines():
                words = line.split()
                for before, word in zip([""] + words, words):
                    if word.endswith(DATA_SUFFIXES) and "/" in word and before not in ("--out", "--log", "--save-plant"):
                        named.append(word)
    assert "docs/examples/my_hammer.toml" in named
    missing = [word for word in named if not (ROOT / word).exists()]
    assert not missing, missing


def test_the_readme_s_own_robot_and_tool_files_run_a_command(tmp_path):
    """The README's commands with its example files: the arm's postures, and a prediction with the
    hammer (the full max-speed searches of the README run in the max-speed tests)."""
    for command in (
        ["postures", "--robot", str(ROOT / "docs/examples/my_arm.toml"), "--json"],
        ["predict", "--robot", "fr3", "--tool", str(ROOT / "docs/examples/my_hammer.toml"), "--posture", "elbow_left",
         "--normal", "-1,0,0", "--speed", "0.1", "--json"],
    ):
        out = subprocess.run([sys.executable, "-m", "impactqp", *command], capture_output=True, text=True, cwd=tmp_path)
        assert out.returncode == 0, out.stderr


def test_the_picture_commands_of_the_simulation_page_parse():
    """Every ``impactqp`` line of the ``sh`` block of docs/simulation.md's "Pictures" is parsed by
    its command's options (an unknown option or a bad value fails; nothing runs), and the docs'
    pictures it made are small files."""
    import click

    from impactqp.scenarios.cli.commands import cli

    text = (ROOT / "docs" / "simulation.md").read_text(encoding="utf-8")
    section = text[text.index("## Pictures"):]
    lines = [line.split()[1:] for block in SH_FENCE.findall(section) for line in block.splitlines()
             if line.startswith("impactqp ")]
    assert {words[0] for words in lines} == {"simulate", "campaign", "max-speed"}
    for words in lines:
        context = cli.commands[words[0]].make_context(words[0], words[1:])
        assert isinstance(context, click.Context)
    for name in ("panda-impact.gif", "panda-impact.png", "panda-velocities.png"):
        assert f"figures/{name}" in section and (ROOT / "docs" / "figures" / name).stat().st_size < 1.5e6
