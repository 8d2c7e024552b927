"""Aligned text tables for the terminal: the one formatter every command prints with.

Only the standard library; cells are strings (format numbers before), columns are separated by
``gap``, the first column is left-aligned and the others right-aligned unless ``align`` says
otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence


def text_table(rows: Sequence[Sequence[str]], *, header: Sequence[str] | None = None, align: str | None = None,
               indent: str = "", gap: str = "  ", rule: bool = False) -> list[str]:
    """Lines of ``rows`` (and ``header`` first) with every column padded to its widest cell.

    Parameters
    ----------
    rows : sequence of sequences of str
        The cells, one sequence per line; shorter rows are padded with empty cells.
    header : sequence of str, optional
        The column names, printed first (and underlined with dashes when ``rule``).
    align : str, optional
        ``"l"`` or ``"r"`` per column (default: the first column left, the others right).
    indent, gap : str
        Put before every line, and between columns.
    rule : bool
        A line of dashes under the header.

    Returns
    -------
    list of str
        The lines, without trailing spaces.
    """
    body = [[str(c) for c in r] for r in rows]
    all_rows = ([list(map(str, header))] if header is not None else []) + body
    if not all_rows:
        return []
    n = max(len(r) for r in all_rows)
    all_rows = [r + [""] * (n - len(r)) for r in all_rows]
    align = (align or ("l" + "r" * (n - 1))).ljust(n, "r")
    if set(align) - {"l", "r"}:
        raise ValueError(f"align: {align!r}; give 'l' or 'r' per column")
    widths = [max(len(r[i]) for r in all_rows) for i in range(n)]

    def line(r):
        cells = [c.ljust(w) if a == "l" else c.rjust(w) for c, w, a in zip(r, widths, align, strict=True)]
        return (indent + gap.join(cells)).rstrip()

    out = [line(r) for r in all_rows]
    if header is not None and rule:
        out.insert(1, (indent + gap.join("-" * w for w in widths)).rstrip())
    return out
