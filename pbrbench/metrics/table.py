"""The metrics table: every score name with its direction, unit and meaning.

Each metrics module exports ``METRICS``, built with :func:`table`; :mod:`pbrbench.metrics`
merges them.  A task scores with the functions of the metrics modules and stores whatever names
they return; the direction and unit come from here, so no task restates them, and a score name
that is in no table is an error (it would otherwise be silently "lower is better").
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Metric:
    """One score name: ``better`` is "lower" or "higher"; ``function`` produces it; ``lower`` is the
    smallest value the score can take (every score of the tables is an error, a fraction or a
    count: 0).  The report does not show a bias-corrected value below it
    (:data:`pbrbench.report.effects.METRIC_LOWER_BOUND`)."""

    name: str
    better: str
    unit: str
    description: str
    function: str = ""
    lower: float = 0.0

    def __post_init__(self):
        if self.better not in ("lower", "higher"):
            raise ValueError(f"metric {self.name!r}: better={self.better!r}; use 'lower' or 'higher'")


def table(*rows) -> dict[str, Metric]:
    """``{name: Metric}`` from rows ``(name, better, unit, description, function)``, or from one
    text block with a row per line, ``name | better | unit | function | description`` (``-`` for
    an empty unit or function), which is how the metrics modules write their tables."""
    if len(rows) == 1 and isinstance(rows[0], str):
        rows = tuple(_parse_row(line) for line in rows[0].splitlines() if line.strip())
    out: dict[str, Metric] = {}
    for r in rows:
        m = Metric(*r)
        if m.name in out:
            raise ValueError(f"metric {m.name!r} is listed twice")
        out[m.name] = m
    return out


def _parse_row(line: str) -> tuple[str, str, str, str, str]:
    cells = [c.strip() for c in line.split("|", 4)]
    if len(cells) != 5 or not all(cells):
        raise ValueError(f"metrics table row {line.strip()!r}: expected 'name | better | unit | function | "
                         "description' ('-' for an empty unit or function)")
    name, better, unit, function, description = cells
    return name, better, "" if unit == "-" else unit, description, "" if function == "-" else function


def merge(*tables: dict[str, Metric]) -> dict[str, Metric]:
    """One table from several; a name listed twice must mean the same (direction and unit)."""
    out: dict[str, Metric] = {}
    for t in tables:
        for name, m in t.items():
            old = out.get(name)
            if old is not None and (old.better, old.unit) != (m.better, m.unit):
                raise ValueError(f"metric {name!r} is defined twice with different meaning: "
                                 f"{old.better}/{old.unit!r} and {m.better}/{m.unit!r}")
            out.setdefault(name, m)
    return out


# metrics every task may report about an algorithm's run itself
STATUS = table("""
failed    | lower  | 0/1 | - | 1 when the algorithm raised or returned an unusable result (message in the report)
converged | higher | 0/1 | - | 1 when an iterative method met its own tolerance
""")
