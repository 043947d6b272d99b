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
