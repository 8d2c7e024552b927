"""The metrics tables' text form: rows parsed into the same Metric records as tuples give."""

import pytest

from pbrbench.metrics import METRICS
from pbrbench.metrics.table import Metric, table


def test_text_rows_equal_tuple_rows():
    text = table("""
    height_rmse | lower  | world units | sfs_scores | height RMSE after removing the free offset
    failed      | lower  | 0/1         | -          | 1 when the algorithm raised | or returned junk
    ratio       | higher | -           | f          | a unitless ratio
    """)
    assert text == table(("height_rmse", "lower", "world units", "height RMSE after removing the free offset",
                          "sfs_scores"),
                         ("failed", "lower", "0/1", "1 when the algorithm raised | or returned junk", ""),
                         ("ratio", "higher", "", "a unitless ratio", "f"))
    assert text["ratio"] == Metric("ratio", "higher", "", "a unitless ratio", "f")


@pytest.mark.parametrize("row", ["a | lower | u | f", "a | lower |  | f | meaning", "a | worse | u | f | meaning"])
def test_a_bad_row_is_refused(row):
    with pytest.raises(ValueError, match="expected 'name | better|better='"):
        table(row)


def test_every_module_table_parses_with_directions_and_meanings():
    assert len(METRICS) > 30
    assert all(m.better in ("lower", "higher") and len(m.description) > 10 for m in METRICS.values())
