"""Text from a bundle or report (a scene's or object's name, an error message) printed into a Markdown file
(runs.md, baseline.md): a Markdown viewer renders raw HTML and reads `|` as a cell's end, so a bundle named
`<img src=x onerror=...>` would run in the page a CI job shows (report.html escapes the same names)."""
from __future__ import annotations

import html

from vdmbake.errors import escaped


def cell(value) -> str:
    """`value` as Markdown text of one table cell: unprintable characters escaped as Python writes them, HTML's
    special characters as entities (CommonMark §6.6: raw HTML is passed through), and `|` as `\\|` (GFM tables)."""
    return html.escape(escaped(str(value)), quote=False).replace("|", "\\|")


def number(v, digits: int, signed: bool = False) -> str:
    """A figure of a Markdown table: `digits` decimals (with its sign if `signed`), or "-" where there is none."""
    return "-" if v is None else f"{v:{'+' if signed else ''}.{digits}f}"


def table(header: list[str], align: str, rows) -> str:
    """A GFM table: the header, its rule with each column aligned as `align` says ('l' left, 'r' right, one letter a
    column), then each row of cells (strings, already made Markdown by `cell` and `number`)."""
    rule = "|" + "".join("---|" if a == "l" else "---:|" for a in align)
    return "\n".join(["| " + " | ".join(header) + " |", rule, *("| " + " | ".join(r) + " |" for r in rows)])
