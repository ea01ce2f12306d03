"""vdmrender.common.markdown: the one table builder and the cell/number formatters every Markdown file of a run
(lod.md, baseline.md, runs.md, composite.md) is made of."""
from __future__ import annotations

from vdmrender.common.markdown import cell, number, table


def test_table_rule_aligns_each_column_and_rows_follow():
    text = table(["name", "ms"], "lr", [["a", "1.0"], ["b", "-"]])
    assert text.splitlines() == ["| name | ms |", "|---|---:|", "| a | 1.0 |", "| b | - |"]


def test_a_hostile_name_stays_in_its_cell():
    rows = [[cell("x | <img src=y onerror=z>"), number(None, 2), number(0.25, 2, True)]]
    line = table(["n", "v", "d"], "lrr", rows).splitlines()[2]
    assert line == "| x \\| &lt;img src=y onerror=z&gt; | - | +0.25 |"
    assert line.count(" | ") == 2            # three cells: the escaped bar does not split one
