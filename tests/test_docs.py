"""Docs that run: every fenced block of the README and of ``docs/*.md`` is exercised.

- ``python`` blocks run in a fresh interpreter;
- ``toml``, ``yaml`` and ``json`` blocks parse, and load through the project's own readers when
  they are one of its files (a robot or tool description, a controller configuration, a sweep
  config, a dataset manifest);
- ``sh``/``bash``/``shell`` blocks pass ``bash -n``, each ``impactqp ...`` line of them is parsed by
  the real click command (``make_context``: no execution), and the cheap ones run in a tmp dir;
- ``text``/``console`` blocks are not run, but their ``impactqp ...`` usage lines (``[...]``
  optional, ``A|B`` alternatives) name only existing commands and options;
- any other language tag, or none, fails.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
SHELLS = ("sh", "bash", "shell")
NOT_RUN = ("text", "console")
EXERCISED = ("python", "toml", "yaml", "json", *SHELLS, *NOT_RUN)


def fenced_blocks(text: str) -> list[tuple[int, str, str]]:
    """(line of the opening fence, language tag, code) of every fenced block of a Markdown text."""
    return [(text.count("\n", 0, m.start()) + 1, m.group(1).strip(), m.group(2)) for m in FENCE.finditer(text)]


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(line of the opening fence, code) of every fenced ``python`` block of a Markdown text."""
    return [(line, code) for line, language, code in fenced_blocks(text) if language == "python"]


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


ALL_BLOCKS = [
    (f"{path.relative_to(ROOT)}:{line}", language, code)
    for path in documents()
    for line, language, code in fenced_blocks(path.read_text(encoding="utf-8"))
]


def blocks(*languages: str) -> list:
    """pytest parameters (id: file and line) of the blocks in these languages."""
    return [pytest.param(code, id=name) for name, language, code in ALL_BLOCKS if language in languages]


def test_blocks_are_found_with_their_line_and_language():
    text = "intro\n```sh\nmake test\n```\n\n```python\nx = 1\n```\n```python  \ny = 2\nprint(y)\n```\n```\nz\n```\n"
    assert python_blocks(text) == [(6, "x = 1\n"), (9, "y = 2\nprint(y)\n")]
    assert [(line, language) for line, language, _ in fenced_blocks(text)] == [(2, "sh"), (6, "python"), (9, "python"), (13, "")]


def test_every_block_has_a_language_the_tests_exercise():
    """A block without a tag, or with one nothing here reads, would escape the tests."""
    unknown = [f"{name} ({language or 'no tag'})" for name, language, _ in ALL_BLOCKS if language not in EXERCISED]
    assert not unknown, unknown


@pytest.mark.parametrize("code", blocks("python"))
def test_every_python_block_runs(code, tmp_path):
    # a fresh interpreter per block, in an empty directory (a block's files stay out of the checkout)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr


CONTROLLER_KEYS = {"dt", "solver", "robot", "tool", "tasks", "limits", "impact", "surface", "post_impact", "libfranka"}


def load_project_file(data: dict, code: str, suffix: str, tmp_path: Path) -> object | None:
    """The project's reader of the file ``data`` (parsed from ``code``) is, applied to it; None for a
    mapping that is none of the project's files."""
    import shutil

    from impactqp.controller.config import ControllerConfig
    from impactqp.controller.model.robot_description import ROBOTS, robot_description
    from impactqp.controller.model.tool_description import tool_description
    from impactqp.scenarios.sweep.config import load_config

    path = tmp_path / f"block{suffix}"
    path.write_text(code, encoding="utf-8")
    if "base" in data:  # a robot description, with the UR5's URDF in place of the file it names
        shutil.copy(ROBOTS["ur5"].urdf_path(), tmp_path / data["urdf"])
        robot = robot_description(path)
        assert robot.name == data["name"] and set(robot.postures) == set(data.get("postures", {}))
        return robot
    if {"frame", "contact_point"} <= set(data):
        return tool_description(path)
    if "grid" in data:
        return load_config(path)
    if set(data) <= CONTROLLER_KEYS:
        return ControllerConfig.from_file(path)
    return None


@pytest.mark.parametrize("code", blocks("toml"))
def test_every_toml_block_loads_through_its_reader(code, tmp_path):
    """Every ``toml`` block is valid TOML, and a robot or tool description, a controller
    configuration (or a table of one) or a sweep config loads through the real reader."""
    data = tomllib.loads(code)
    assert load_project_file(data, code, ".toml", tmp_path) is not None, sorted(data)


@pytest.mark.parametrize("code", blocks("yaml"))
def test_every_yaml_block_is_a_controller_configuration(code, tmp_path):
    """YAML is read by one loader, the controller configuration's."""
    import yaml

    from impactqp.controller.config import ControllerConfig

    data = yaml.safe_load(code)
    config = load_project_file(data, code, ".yaml", tmp_path)
    assert isinstance(config, ControllerConfig)
    assert config.dt == data.get("dt", config.dt) and config.solver == data.get("solver", config.solver)


@pytest.mark.parametrize("code", blocks("json"))
def test_every_json_block_parses_and_a_manifest_loads(code):
    """Every ``json`` block is valid JSON; a dataset manifest's header and trials load through the
    dataset's own parsers."""
    from impactqp.controller.measured.dataset import FORMAT, parse_entry, parse_header

    data = json.loads(code)
    if isinstance(data, dict) and data.get("format") == FORMAT:
        header = parse_header(data)
        assert header.robot == data["robot"]
        assert [parse_entry(entry).id for entry in data["trials"]] == [entry["id"] for entry in data["trials"]]


def shell_commands(code: str) -> list[list[str]]:
    """The words of every command of a shell block: continuation lines joined, comments dropped,
    the command's own words only (up to a redirection, a pipe or a list operator)."""
    commands = []
    for line in code.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        operator = next((i for i, word in enumerate(words) if word.lstrip("0123456789")[:1] in ("<", ">", "|", "&", ";")),
                        len(words))
        if words[:operator]:
            commands.append(words[:operator])
    return commands


def resolve(words: list[str]):
    """(click command, its name path, its arguments) of an ``impactqp ...`` command line."""
    from impactqp.scenarios.cli.commands import cli

    command, path, args = cli, ["impactqp"], list(words[1:])
    while hasattr(command, "get_command"):  # a group: its own flags (--debug, --quiet...), then a subcommand
        flags = {name for param in command.params if getattr(param, "is_flag", False) for name in param.opts}
        while args and args[0] in flags | {"--debug"}:
            args.pop(0)
        assert args, f"{' '.join(words)}: no command"
        name = args.pop(0)
        sub = command.get_command(None, name)
        assert sub is not None, f"{' '.join(words)}: unknown command {name!r}"
        command, path = sub, [*path, name]
    return command, path, args


def parse_command(words: list[str]) -> None:
    """Parse an ``impactqp`` command line with the real click command, without running it."""
    import click

    command, path, args = resolve(words)
    try:
        with command.make_context(" ".join(path), args):
            pass
    except click.exceptions.Exit as exit_:  # an eager option such as --example
        assert exit_.exit_code == 0


SHELL_COMMANDS = [
    pytest.param(words, id=f"{name}:{' '.join(words[:3])}")
    for name, language, code in ALL_BLOCKS
    if language in SHELLS
    for words in shell_commands(code)
    if words[0] == "impactqp"
]


@pytest.mark.parametrize("code", blocks(*SHELLS))
def test_every_shell_block_is_valid_bash(code, tmp_path):
    script = tmp_path / "block.sh"
    script.write_text(code, encoding="utf-8")
    out = subprocess.run(["bash", "-n", str(script)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


@pytest.mark.parametrize("words", SHELL_COMMANDS)
def test_every_impactqp_command_of_a_shell_block_parses(words, monkeypatch):
    """Unknown commands, unknown options, bad values and missing required options fail; relative
    paths are the repository's (the docs' commands run from a clone)."""
    monkeypatch.chdir(ROOT)
    parse_command(words)


def test_the_command_parser_refuses_what_the_cli_refuses():
    import click

    parse_command(["impactqp", "predict", "--posture", "elbow_up", "--normal", "-1,0,0", "--speed", "0.1"])
    with pytest.raises(AssertionError, match="unknown command"):
        parse_command(["impactqp", "predikt", "--speed", "0.1"])
    for bad in (["--speeed", "0.1"], ["--speed", "fast"], []):  # unknown option, bad value, missing required
        with pytest.raises(click.UsageError):
            parse_command(["impactqp", "predict", "--normal", "-1,0,0", *bad])
    with pytest.raises(click.UsageError):
        parse_command(["impactqp", "dataset", "validate"])  # a subgroup's command without its argument


CHEAP_COMMANDS = ("predict", "postures")
SMALL = {"max-speed": ["--tolerance", "0.5"]}
"""Extra options that make a command of the README's first screen cheap enough for a test."""


def readme_first_screen() -> str:
    return "\n".join((ROOT / "README.md").read_text(encoding="utf-8").splitlines()[:40])


def readme_commands() -> list[list[str]]:
    return [
        words
        for language, code in re.findall(r"^```(\w*)\n(.*?)^```", readme_first_screen(), re.MULTILINE | re.DOTALL)
        if language in SHELLS
        for words in shell_commands(code)
        if words[0] == "impactqp"
    ]


def test_the_readme_s_first_screen_starts_a_user():
    """Within 40 lines: one picture, the install line, the clone's two commands and the three
    commands that matter."""
    screen = readme_first_screen()
    pictures = re.findall(r"^!\[[^\]]+\]\(([^)\s]+)\)$", screen, re.MULTILINE)
    assert len(pictures) == 1 and (ROOT / pictures[0]).is_file(), pictures
    lines = [line.split("#")[0].strip() for line in screen.splitlines()]
    assert "pip install impactqp" in lines and "make demo" in lines and "make test" in lines
    assert [words[1] for words in readme_commands()] == ["predict", "simulate", "max-speed"]


RUN_COMMANDS = [
    pytest.param(words, id=" ".join(words[:3]))
    for words in [*readme_commands(), *(p.values[0] for p in SHELL_COMMANDS if p.values[0][1] in CHEAP_COMMANDS)]
]


@pytest.mark.parametrize("words", RUN_COMMANDS)
def test_the_cheap_commands_and_the_readme_s_three_run(words, tmp_path):
    """In an empty directory (the docs' relative paths reach the repository's ``docs/``)."""
    (tmp_path / "docs").symlink_to(ROOT / "docs")
    command = [sys.executable, "-m", "impactqp", *words[1:], *SMALL.get(words[1], [])]
    out = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["docs"] or "--out" in words


USAGE_WORD = re.compile(r"--[a-z][a-z0-9-]*")


def usage_lines(code: str) -> list[str]:
    """The ``impactqp ...`` usage lines of a text block, continuation lines joined."""
    joined = code.replace("\\\n", " ").splitlines()
    return [line.strip().removeprefix("$ ") for line in joined if line.strip().removeprefix("$ ").startswith("impactqp ")]


USAGES = [
    pytest.param(line, id=f"{name}:{' '.join(line.split()[:2])}")
    for name, language, code in ALL_BLOCKS
    if language in NOT_RUN
    for line in usage_lines(code)
]


def check_usage(line: str) -> None:
    """The command of a usage line exists and every ``--option`` it names is one of its options."""
    words = [w for w in re.split(r"[\s\[\]|]+", line) if w]
    command_words = ["impactqp"]
    for word in words[1:]:
        if word.startswith("-") or not re.fullmatch(r"[a-z][a-z-]*", word):
            break
        command_words.append(word)
    from impactqp.scenarios.cli.commands import cli

    command = cli
    for name in command_words[1:]:
        if not hasattr(command, "get_command"):
            break
        sub = command.get_command(None, name)
        assert sub is not None, f"{line}: unknown command {name!r}"
        command = sub
    known = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
    unknown = sorted(set(USAGE_WORD.findall(line)) - known)
    assert not unknown, f"{line}: unknown options {unknown}"


@pytest.mark.parametrize("line", USAGES)
def test_every_usage_line_names_existing_options(line):
    check_usage(line)


def test_the_usage_check_refuses_an_unknown_option():
    check_usage("impactqp predict --posture P [--json]")
    with pytest.raises(AssertionError, match="--tool-frame"):
        check_usage("impactqp dataset import-franka OUT [--tool-frame NAME]")


SH_FENCE = re.compile(r"^```(?:sh|bash|shell|text)[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)
DATA_SUFFIXES = (".toml", ".json", ".yaml", ".yml")


def test_the_example_files_load_and_every_input_file_a_shell_block_names_ships():
    """``docs/examples`` holds the docs' own tool and robot files, which load through the real
    readers; every ``.toml``/``.json``/``.yaml`` input a shell or usage block of the docs names with
    a path ships in the repository (an output file, after ``--out``/``--log``/``--save-plant``,
    need not)."""
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


def test_the_docs_own_robot_and_tool_files_run_a_command(tmp_path):
    """The docs' commands with their example files: the arm's postures, and a prediction with the
    hammer (the full max-speed searches of docs/robots.md run in the max-speed tests)."""
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
    start = text.index("## Pictures")
    section = text[start:text.find("\n## ", start + 1) if "\n## " in text[start + 1:] else len(text)]
    lines = [line.split()[1:] for block in SH_FENCE.findall(section) for line in block.splitlines()
             if line.startswith("impactqp ")]
    assert {words[0] for words in lines} == {"simulate", "campaign", "max-speed"}
    for words in lines:
        context = cli.commands[words[0]].make_context(words[0], words[1:])
        assert isinstance(context, click.Context)
    for name in ("panda-impact.gif", "panda-impact.png", "panda-velocities.png"):
        assert f"figures/{name}" in section and (ROOT / "docs" / "figures" / name).stat().st_size < 1.5e6
