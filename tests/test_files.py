"""The one reader of configuration and data files: regular files only, UTF-8, bounded, one line."""

import json
import os
import time

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from impactqp.controller.model import files
from impactqp.controller.model.files import read_mapping, read_text, regular_file
from impactqp.controller.model.validation import MAX_MESSAGE_CHARACTERS, BadInputError


class OwnError(BadInputError):
    """A caller's own kind of bad input (as DatasetError or PlantParameterError)."""


def test_a_regular_file_is_returned_as_a_path(tmp_path):
    path = tmp_path / "a.json"
    path.write_text("{}")
    assert regular_file(str(path), "the file") == path


@pytest.mark.parametrize("make, fragment", [
    (lambda p: None, "does not exist"),
    (lambda p: p.mkdir(), "is a directory"),
    (lambda p: os.mkfifo(p), "not a regular file"),
])
def test_anything_but_a_regular_file_is_one_line_of_the_callers_kind_without_opening_it(tmp_path, make, fragment):
    """A FIFO is refused before it is opened (opening it would block until a writer comes)."""
    path = tmp_path / "c.toml"
    make(path)
    for read in (
        lambda: regular_file(path, "the sweep config", OwnError),
        lambda: read_mapping(path, "the sweep config", error=OwnError),
    ):
        with pytest.raises(OwnError) as caught:
            read()
        message = str(caught.value)
        assert fragment in message and message.startswith(f"the sweep config {path}") and "\n" not in message


def test_a_device_is_not_a_regular_file():
    with pytest.raises(BadInputError, match="not a regular file"):
        read_text("/dev/zero", "the plant parameter file")


def test_a_path_under_a_file_does_not_exist(tmp_path):
    (tmp_path / "f").write_text("")
    with pytest.raises(BadInputError, match="does not exist"):
        regular_file(tmp_path / "f" / "c.json", "the file")


def test_a_byte_order_mark_is_not_part_of_the_text(tmp_path):
    path = tmp_path / "c.toml"
    path.write_bytes(b"\xef\xbb\xbfdt = 0.002\n")
    assert read_text(path, "the file") == "dt = 0.002\n"
    assert read_mapping(path, "the file") == {"dt": 0.002}


def test_text_that_is_not_utf8_is_bad_input(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(BadInputError, match=f"the file {path} is not a UTF-8 text file"):
        read_mapping(path, "the file")


def test_a_file_above_the_size_bound_is_bad_input(tmp_path, monkeypatch):
    path = tmp_path / "c.json"
    path.write_text('{"a": 1}')
    monkeypatch.setattr(files, "MAX_FILE_BYTES", path.stat().st_size)
    assert read_mapping(path, "the file") == {"a": 1}
    monkeypatch.setattr(files, "MAX_FILE_BYTES", path.stat().st_size - 1)
    with pytest.raises(BadInputError, match="larger than"):
        read_mapping(path, "the file")


@pytest.mark.parametrize("name, content, syntax, fragment", [
    ("c.yaml", b"dt: [1\n", None, "not valid YAML"),
    ("c.toml", b"dt = \n", None, "not valid TOML"),
    ("c.json", b"{armature: 1", None, "not valid JSON"),
    ("c.cfg", b"[grid\n", "toml", "not valid TOML"),
    ("c.yaml", b"- 1\n- 2\n", None, "must be a table of keys and values, got list"),
    ("c.json", b"[1, 2]", None, "must be a JSON object, got list"),
    ("c.yaml", b"x: " + b"[" * 100_000 + b"]" * 100_000, None, "nested too deeply"),
    ("c.json", b"[" * 100_000 + b"]" * 100_000, None, "nested too deeply"),
    ("c.txt", b"{}", None, "unsupported file type"),
    ("c.yaml", b"dt: 0.001\ndt: 0.002\n", None, "not valid YAML: the key 'dt' is given twice"),
    ("c.yaml", b"impact:\n  jump_model: crb\n  jump_model: gm\n", None, "the key 'jump_model' is given twice"),
    ("c.json", b'{"mass": 0.5, "frame": "hand", "mass": 1.0}', None, "not valid JSON: the key 'mass' is given twice"),
    ("c.json", b'{"a": {"b": 1, "b": 2}}', None, "the key 'b' is given twice"),
])
def test_bad_content_is_one_line_that_names_the_file(tmp_path, name, content, syntax, fragment):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(OwnError) as caught:
        read_mapping(path, "the configuration", syntax, OwnError)
    message = str(caught.value)
    assert fragment in message and str(path) in message and "\n" not in message
    assert path.read_bytes() == content


def test_an_empty_yaml_document_is_an_empty_table(tmp_path):
    path = tmp_path / "c.yml"
    path.write_text("# nothing yet\n")
    assert read_mapping(path, "the file") == {}


words = st.characters(whitelist_categories=("L", "Nd", "Zs"))  # YAML folds some control characters
keys = st.text(words, min_size=1, max_size=8)
values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**40), 2**40) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(words, max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(keys, children, max_size=3),
    max_leaves=10,
)


@settings(max_examples=40, deadline=None)
@given(table=st.dictionaries(keys, values, max_size=5), suffix=st.sampled_from([".json", ".yaml"]))
def test_a_written_table_reads_back_equal(tmp_path_factory, table, suffix):
    path = tmp_path_factory.mktemp("files") / f"c{suffix}"
    text = json.dumps(table) if suffix == ".json" else yaml.safe_dump(table, allow_unicode=True)
    path.write_text(text, encoding="utf-8")
    assert read_mapping(path, "the file") == table


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from([".json", ".toml", ".yaml"]),
    st.one_of(st.integers(19, 6000), st.just(5000)),
    st.booleans(),
)
def test_an_integer_beyond_64_bits_is_one_line_before_any_conversion(tmp_path_factory, suffix, digits, negative):
    """An integer of 19 to thousands of digits, in every syntax (a tool's mass, a manifest's
    field, a grid size): one line of bad input naming the file, quickly."""
    number = ("-" if negative else "") + "9" * digits
    path = tmp_path_factory.mktemp("huge") / f"f{suffix}"
    path.write_text({".json": f'{{"mass": {number}}}', ".toml": f"mass = {number}\n", ".yaml": f"mass: {number}\n"}[suffix])
    start = time.perf_counter()
    with pytest.raises(BadInputError) as caught:
        read_mapping(path, "the file")
    message = str(caught.value)
    assert str(path) in message and len(message.splitlines()) == 1 and len(message) <= MAX_MESSAGE_CHARACTERS
    assert time.perf_counter() - start < 5.0


def test_yaml_aliases_are_refused_so_an_alias_bomb_cannot_expand(tmp_path):
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, 9):
        lines.append(f"{chr(97 + k)}: &{chr(97 + k)} [{', '.join([f'*{chr(96 + k)}'] * 9)}]")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    start = time.perf_counter()
    with pytest.raises(BadInputError, match="aliases"):
        read_mapping(path, "the configuration")
    assert time.perf_counter() - start < 5.0


def test_a_bad_input_message_quoting_a_huge_value_is_cut():
    message = str(BadInputError(f"speeds must be numbers, got {list(range(100000))!r}"))
    assert len(message) <= MAX_MESSAGE_CHARACTERS and message.endswith("(cut)")
