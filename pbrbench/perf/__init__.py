"""Speed and accuracy benchmarks of the inference kernels and the renderer (``pbrbench perf``).

Each module ``pbrbench.perf.<area>`` exposes ``run(quick=False) -> list[dict]`` with rows
``{"benchmark", "case", "method", "metric", "value", "unit", "better"}`` (made by :func:`row`: every
metric states whether lower or higher is better, nothing is guessed from its name) and a
``main()`` that prints them.
"""

from __future__ import annotations

import sys


def row(benchmark: str, case: str, method: str, metric: str, value, unit: str = "", *, better: str) -> dict:
    """One perf row; ``better`` is ``"lower"`` or ``"higher"`` (required: the stored score and the
    comparison of two perf runs read it)."""
    if better not in ("lower", "higher"):
        raise ValueError(f"perf row {benchmark}/{metric}: better={better!r}; say 'lower' or 'higher'")
    return {"benchmark": benchmark, "case": case, "method": method, "metric": metric, "value": float(value),
            "unit": unit, "better": better}


def print_rows(rows: list[dict]) -> None:
    """Print perf rows as an aligned table: case, method, metric, value and unit."""
    if not rows:
        print("(no rows)")
        return
    from pbrbench.text import text_table

    for line in text_table([(r["case"], r["method"], r["metric"], f"{r['value']:.4g} {r['unit']}") for r in rows],
                           align="llll"):
        print(line)


def main_for(run, argv=None) -> None:
    """``python -m pbrbench.perf.<area> [--quick]``: run and print."""
    argv = sys.argv[1:] if argv is None else argv
    print_rows(run(quick="--quick" in argv))
