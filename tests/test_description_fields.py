"""Reading a description's fields (controller/model/description_fields.py)."""

import pytest

from impactqp.controller.model.description_fields import (
    MAX_JOINTS,
    name_field,
    named_tables_field,
    names_field,
    table_field,
)
from impactqp.controller.model.validation import BadInputError


def test_good_fields_are_returned_as_read():
    assert names_field(["a", "b"], "joints") == ("a", "b")
    assert name_field("a", "name") == "a"
    assert table_field({"t": {"x": 1}}, "t", {"x", "y"}, "robot") == {"x": 1}
    assert table_field({}, "t", {"x"}, "robot") == {}
    assert named_tables_field({"s": {"a": {}, "b": {}}}, "s", "robot") == {"a": {}, "b": {}}


@pytest.mark.parametrize("read", [
    lambda: names_field(["a", "a"], "joints"),
    lambda: names_field([str(i) for i in range(MAX_JOINTS + 1)], "joints"),
    lambda: names_field("a", "joints"),
    lambda: name_field("", "name"),
    lambda: table_field({"t": 3}, "t", {"x"}, "robot"),
    lambda: table_field({"t": {"z": 1}}, "t", {"x"}, "robot"),
    lambda: named_tables_field({"s": {"a": 1}}, "s", "robot"),
])
def test_a_bad_field_is_one_line_of_bad_input(read):
    with pytest.raises(BadInputError) as error:
        read()
    assert "\n" not in str(error.value)
