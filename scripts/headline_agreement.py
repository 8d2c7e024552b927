"""Do two runs' headline cells agree within their standard errors?

    python scripts/headline_agreement.py STORE_A RUN_A STORE_B RUN_B

For every headline cell (task, algorithm, column) of both runs (pbrbench.report.effects), the two
values agree when they differ by at most 2 combined standard errors plus the comparisons' small
floor (1e-6 + 1e-3 |value|: float32 rounding of an exact solve).  Prints the fraction that agree
and the cells that do not.  Used to check the standard errors on two runs whose scene files differ
only in their render seeds.
"""

from __future__ import annotations

import math
import sys


def cells(store_path: str, run_id: str):
    from pbrbench.bench.store import Store
    from pbrbench.report.effects import effect_tables
    from pbrbench.report.html import geometry_of

    with Store(store_path) as st:
        run_id = st.resolve_run(run_id)
        info = st.get_run(run_id)["config"].get("task_info", {})
        tables = effect_tables(st.scores(run_id), info, geometry_of(st.ground_truths(run_id)))
    out = {}
    for t in tables:
        for r in t["rows"]:
            for col, c in zip(t["columns"], r["cells"], strict=True):
                if c is not None and math.isfinite(c["value"]):
                    out[(t["task"], r["algorithm"], col["label"])] = c
    return out


def main(argv):
    a, b = cells(argv[0], argv[1]), cells(argv[2], argv[3])
    common = sorted(set(a) & set(b))
    bad = []
    for k in common:
        x, y = a[k], b[k]
        se = math.sqrt((x["se"] if math.isfinite(x["se"]) else 0.0) ** 2 + (y["se"] if math.isfinite(y["se"]) else 0.0) ** 2)
        tol = 2.0 * se + 1e-6 + 1e-3 * max(abs(x["value"]), abs(y["value"]))
        if abs(x["value"] - y["value"]) > tol:
            bad.append((k, x["value"], y["value"], tol))
    n = len(common)
    print(f"{n - len(bad)} of {n} headline cells agree within 2 combined standard errors ({100 * (n - len(bad)) / max(n, 1):.1f} %)")
    # what the SE model itself expects: with exact standard errors estimated on nu degrees of
    # freedom, the difference over its combined SE is Student's t on the Welch-Satterthwaite dof,
    # and |t| <= 2 holds with probability P(nu) < 0.954 (0.908 at nu = 6)
    from scipy import stats

    from pbrbench.uncertainty import combined

    def _p(x, y):
        se_x, se_y = (c["se"] if math.isfinite(c["se"]) else 0.0 for c in (x, y))
        _, nu = combined((se_x, x.get("dof") or math.inf), (se_y, y.get("dof") or math.inf))
        return float(stats.norm.cdf(2) - stats.norm.cdf(-2)) if not math.isfinite(nu) else float(stats.t.cdf(2, nu) - stats.t.cdf(-2, nu))

    expect = sum(_p(a[k], b[k]) for k in common)
    print(f"  expected with exact standard errors on the cells' degrees of freedom: {expect:.1f} of {n} "
          f"({100 * expect / max(n, 1):.1f} %)")

    def _t_ok(x, y):
        se_x, se_y = (c["se"] if math.isfinite(c["se"]) else 0.0 for c in (x, y))
        se, nu = combined((se_x, x.get("dof") or math.inf), (se_y, y.get("dof") or math.inf))
        tq = float(stats.norm.ppf(0.975)) if not math.isfinite(nu) else float(stats.t.ppf(0.975, nu))
        return abs(x["value"] - y["value"]) <= tq * se + 1e-6 + 1e-3 * max(abs(x["value"]), abs(y["value"]))

    nt_ok = sum(1 for k in common if _t_ok(a[k], b[k]))
    print(f"  within the 95 % Student-t interval of the difference (its Welch-Satterthwaite dof): {nt_ok} of {n} "
          f"({100 * nt_ok / max(n, 1):.1f} %; 95 % expected)")
    unst = {k for k in common if a[k].get("unstable") or b[k].get("unstable")}
    ns = n - len(unst)
    bs = sum(1 for k, *_ in bad if k not in unst)
    print(f"  without the {len(unst)} cells the report shades as bimodal in either run: {ns - bs} of {ns} "
          f"({100 * (ns - bs) / max(ns, 1):.1f} %)")
    for task in sorted({k[0] for k in common}):
        nt = sum(1 for k in common if k[0] == task)
        bt = sum(1 for k, *_ in bad if k[0] == task)
        et = sum(_p(a[k], b[k]) for k in common if k[0] == task)
        print(f"  {task}: {nt - bt} of {nt} ({100 * (nt - bt) / nt:.1f} %; expected {100 * et / nt:.1f} %)")
    for k, x, y, tol in bad:
        print(f"  {' / '.join(k)}: {x:.6g} vs {y:.6g} (allowed {tol:.3g})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
