"""Baselines: tolerance from the measured spread, direction-aware regression detection."""

import math

import pytest

from pbrbench.bench import regress


def s(value, metric="rmse", better="lower", scene="a", alg="m", cond="local", task="t"):
    return {"task": task, "scene": scene, "condition": cond, "algorithm": alg, "metric": metric,
            "value": value, "better": better}


def test_tolerance_is_k_times_spread_with_floor():
    runs = [[s(1.0), s(5.0, "zero_spread")], [s(1.2), s(5.0, "zero_spread")], [s(0.9), s(5.0, "zero_spread")]]
    b = regress.build_baselines(runs, quality="draft", seeds=[0, 1, 2])
    e = b["entries"]["t|a|local|m|rmse"]
    assert e["value"] == 1.0 and e["spread"] == pytest.approx(0.3)
    assert e["tolerance"] == pytest.approx(regress.K * 0.3)
    z = b["entries"]["t|a|local|m|zero_spread"]
    assert z["spread"] == 0 and z["tolerance"] == pytest.approx(regress.ABS_FLOOR + regress.REL_FLOOR * 5.0)
    assert b["seeds"] == [0, 1, 2] and "spread" in b["method"]


def test_build_needs_runs():
    with pytest.raises(ValueError, match="runs"):
        regress.build_baselines([], quality="draft", seeds=[])


def _base(value, tol, better):
    return {"entries": {"t|a|local|m|x": {"task": "t", "scene": "a", "condition": "local", "algorithm": "m",
                                          "metric": "x", "value": value, "better": better, "tolerance": tol}}}


@pytest.mark.parametrize("better,new,kind", [
    ("lower", 1.05, None), ("lower", 1.2, "regression"), ("lower", 0.8, "improvement"),
    ("higher", 0.8, "regression"), ("higher", 1.2, "improvement"), ("higher", 0.95, None),
    ("lower", float("nan"), "regression"),
])
def test_direction_and_tolerance(better, new, kind):
    c = regress.compare([s(new, "x", better)], _base(1.0, 0.1, better))
    got = (c.regressions and "regression") or (c.improvements and "improvement") or None
    assert got == kind
    assert c.ok == (kind != "regression")
    if kind == "regression":
        r = c.regressions[0]
        text = str(r)
        assert r.old == 1.0 and (r.new == new or math.isnan(r.new)) and r.tolerance == 0.1
        assert "x" in text and "old 1" in text and "tolerance 0.1" in text


def test_missing_and_new_keys():
    base = _base(1.0, 0.1, "lower")
    c = regress.compare([s(1.0, "other")], base)
    assert c.missing == ["t|a|local|m|x"] and c.new == ["t|a|local|m|other"]
    # a task that did not run is not reported missing
    c2 = regress.compare([s(1.0, "x", task="u")], base)
    assert c2.missing == []


def test_write_load_roundtrip(tmp_path):
    b = regress.build_baselines([[s(2.0)]], quality="draft", seeds=[0])
    p = regress.write_baselines(b, tmp_path / "draft.json")
    assert regress.load_baselines(p) == b
    assert regress.load_baselines(tmp_path / "none.json") is None
    from pbrbench.bench.run import comparison_record
    from pbrbench.report.html import markers

    assert markers(comparison_record(regress.compare([s(9.0)], b))) == {("t", "m", "local"): "regression"}


def test_changed_scene_is_named_in_the_message():
    b = regress.build_baselines([[dict(s(1.0), scene_hash="aaa")]], quality="draft", seeds=[0])
    c = regress.compare([dict(s(2.0), scene_hash="bbb")], b)
    assert c.regressions[0].scene_changed and "scene file changed" in str(c.regressions[0])
    c2 = regress.compare([dict(s(2.0), scene_hash="aaa")], b)
    assert not c2.regressions[0].scene_changed
