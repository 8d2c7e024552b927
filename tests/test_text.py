"""The one text-table formatter (pbrbench.text)."""

from __future__ import annotations

import pytest

from pbrbench.text import text_table


def test_columns_are_padded_to_the_widest_cell_first_left_then_right():
    lines = text_table([["a", "1"], ["long", "22.5"]], header=["name", "value"], rule=True, indent="  ")
    assert lines == ["  name  value", "  ----  -----", "  a         1", "  long   22.5"]


def test_explicit_alignment_short_rows_and_no_trailing_spaces():
    lines = text_table([["x", "y"], ["xxx"]], align="rl")
    assert lines == ["  x  y", "xxx"]
    assert all(not s.endswith(" ") for s in lines)


def test_bad_alignment_is_refused():
    with pytest.raises(ValueError, match="align"):
        text_table([["a"]], align="c")
