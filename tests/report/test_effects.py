"""The effect tables of the headline: matched scenes, twins, paired and independent standard
errors, significance and the convex / concave split."""

from __future__ import annotations

import math

import pytest

from pbrbench.report.effects import base_scene, effect_tables, match_key
from pbrbench.uncertainty import mean_se, paired_se, significant, standard_error


def s(scene, cond, value, *, alg="m", unc=0.1, rep=None, h=None, dof=1e9, **kw):
    d = {"task": "t", "scene": scene, "condition": cond, "algorithm": alg, "metric": "err", "value": value,
         "better": "lower", "unit": "deg", "uncertainty": unc, "scene_hash": h or base_scene(match_key(scene)),
         "dof": dof, **kw}
    if rep is not None:
        d["replicates"] = list(rep)
    return d


INFO = {"t": {"headline_metric": "err", "conditions": ["local", "area", "global"], "reference_condition": "local"}}


def test_twins_and_labels_match_their_base_scene():
    assert match_key("ps_cup_area[albedo=0.5]") == "ps_cup[albedo=0.5]"
    assert match_key("sfs_vase_area:view") == "sfs_vase:view" and base_scene("sfs_vase:view") == "sfs_vase"
    assert match_key("area_light_scene") == "area_light_scene"


def test_standard_error_from_replicates():
    assert standard_error(1.0, [1.2, 0.8]) == pytest.approx(0.2)
    assert standard_error(1.0, [1.2, 0.8], 1.3) == pytest.approx(math.sqrt(0.04 + 0.09 / 2))
    assert math.isnan(standard_error(1.0))
    m, se, dof = mean_se([1.0, 3.0], [0.3, 0.4], [3, 3])
    assert m == 2.0 and se == pytest.approx(0.25) and 3 < dof < 6
    assert significant(0.5, 0.2) is True and significant(0.3, 0.2) is False and significant(1.0, float("nan")) is None
    # Student's t on few degrees of freedom widens the interval: 0.5 is 2.5 SE, inside t(0.975, 3) = 3.18
    assert significant(0.5, 0.2, dof=3) is False and significant(0.7, 0.2, dof=3) is True


def test_paired_replicates_of_one_render_cancel_their_common_noise():
    # global and local of one render: their noise is shared, the difference of paired halves sees only what differs
    loc = s("x", "local", 1.0, unc=0.5, rep=(1.5, 0.5))
    glo = s("x", "global", 2.0, unc=0.5, rep=(2.52, 1.48))
    assert paired_se(glo, loc) == pytest.approx(0.02)
    # an area twin is another render: independent errors add in quadrature
    area = s("x_area", "area", 2.0, unc=0.5, rep=(2.5, 1.5), h="x_area")
    assert paired_se(area, loc) == pytest.approx(math.sqrt(0.5))


def test_effects_are_averaged_over_matched_scenes_and_split_by_geometry():
    scores = [s("cup", "local", 1.0), s("cup", "global", 9.0), s("ball", "local", 1.0), s("ball", "global", 1.05),
              s("cup_area", "area", 3.0), s("ball_area", "area", 3.0), s("lonely", "local", 100.0)]
    (t,) = effect_tables(scores, INFO, geometry={"cup": "concave", "ball": "convex"})
    labels = [c["label"] for c in t["columns"]]
    assert labels == ["local", "area − local", "global − local", "global − local (concave)", "global − local (convex)"]
    cells = dict(zip(labels, t["rows"][0]["cells"], strict=True))
    assert cells["local"]["n"] == 3 and cells["local"]["value"] == pytest.approx(34.0)
    assert cells["area − local"]["value"] == pytest.approx(2.0) and cells["area − local"]["n"] == 2
    assert cells["global − local"]["value"] == pytest.approx((8.0 + 0.05) / 2)
    assert cells["global − local (concave)"]["significant"] is True
    conv = cells["global − local (convex)"]
    assert conv["value"] == pytest.approx(0.05) and conv["insignificant"] is True  # 0.05 < 2 * sqrt(0.02)
    assert t["noise_floor"] == pytest.approx(0.1) and t["unit"] == "deg"


def test_no_uncertainty_never_makes_an_effect():
    scores = [s("x", "local", 1.0, unc=None), s("x", "global", 5.0, unc=None)]
    (t,) = effect_tables(scores, INFO)
    eff = t["rows"][0]["cells"][1]
    assert eff["value"] == 4.0 and eff["significant"] is None and not eff["insignificant"]


def test_an_algorithm_run_on_a_subset_is_shown_beside_the_others_on_its_scenes():
    # "inv" has no reference score (it runs under global on the cup only): it is not a row of the
    # table (whose cells it cannot fill) but a line beside every algorithm scored on the same scenes
    scores = [s("cup", "local", 1.0), s("cup", "global", 9.0), s("ball", "local", 1.0), s("ball", "global", 2.0),
              s("cup", "global", 3.0, alg="inv", unc=0.3), s("ball", "local", 5.0, alg="ballonly"),
              s("ball", "global", 6.0, alg="ballonly")]
    (t,) = effect_tables(scores, INFO)
    assert [r["algorithm"] for r in t["rows"]] == ["ballonly", "m"]
    (p,) = [p for p in t["partial"] if p["algorithm"] == "inv"]
    assert p["condition"] == "global" and p["scenes"] == ["cup"] and "of" not in p
    assert p["value"] == pytest.approx(3.0) and p["se"] == pytest.approx(0.3)
    assert [(b["algorithm"], b["value"]) for b in p["beside"]] == [("m", pytest.approx(9.0))]  # not ballonly


def test_the_report_prints_the_subset_line(tmp_path):
    from pbrbench.report.html import headline_tables

    scores = [s("cup", "local", 1.0), s("cup", "global", 9.0), s("cup", "global", 3.0, alg="inv", unc=0.3)]
    (h,) = headline_tables(scores, INFO)
    (p,) = h["partial"]
    assert p["text"] == "3 ± 0.3" and p["beside"][0]["text"] == "9 ± 0.1"


def test_rounding_sized_costs_are_not_effects():
    # a convex scene's global and local images are the same render: their scores differ by float32
    # rounding with an even smaller paired SE; that is not a gain
    scores = [s("ball", "local", 9.46, unc=1e-4, rep=(9.46, 9.46)),
              s("ball", "global", 9.46 - 8.8e-11, unc=1e-4, rep=(9.46 - 8.8e-11, 9.46 - 8.7e-11))]
    (t,) = effect_tables(scores, INFO)
    c = t["rows"][0]["cells"][1]
    assert c["value"] == pytest.approx(-8.8e-11, rel=0.05) and c["insignificant"] is True
    scores[1] = s("ball", "global", 9.0, unc=1e-4, rep=(9.0, 9.0))
    (t,) = effect_tables(scores, INFO)
    assert t["rows"][0]["cells"][1]["significant"] is True


def test_noise_limited_and_bimodal_cells_are_marked():
    # a score whose Monte Carlo bias (2.5) exceeds its SE (0.3): marked, with its corrected value
    scores = [s("cup", "local", 1.0, bias=0.0), s("cup", "global", 16.0, unc=0.3, dof=3, bias=2.5)]
    (t,) = effect_tables(scores, INFO)
    ref, eff = t["rows"][0]["cells"]
    assert not ref["noise_limited"] and eff["noise_limited"] and eff["corrected"] == pytest.approx(15.0 - 2.5)
    assert 3 <= eff["dof"] < 4   # Welch-Satterthwaite: the global score's 3 dof dominate
    from pbrbench.report.effects import format_cell

    assert "corrected" in format_cell(eff)
    # bimodal replicates: never called significant, shown as such
    scores = [s("cup", "local", 1.0), s("cup", "global", 9.0, unstable=True)]
    (t,) = effect_tables(scores, INFO)
    eff = t["rows"][0]["cells"][1]
    assert eff["unstable"] and eff["significant"] is None and "bimodal" in format_cell(eff)


def test_a_correction_below_the_metrics_smallest_value_is_withheld():
    # the replicates of a calibration all settle far from its full-sample score (0.0145 against
    # 0.108-0.163): the jackknife bias (+0.38) would make the RMSE negative -- not a correction
    from pbrbench.report.effects import METRIC_LOWER_BOUND, format_cell

    scores = [s("ball", "local", 0.0145, unc=0.039, dof=3, bias=0.384), s("ball", "global", 0.5, unc=0.01, bias=0.0)]
    (t,) = effect_tables(scores, INFO)
    ref, eff = t["rows"][0]["cells"]
    assert ref["noise_limited"] and ref["correction_fails"] and math.isnan(ref["corrected"])
    assert "no correction" in format_cell(ref) and "corrected" not in format_cell(ref)
    # the difference is built on that score too: its correction is withheld as well
    assert eff["correction_fails"] and math.isnan(eff["corrected"])
    # a bias that leaves the corrected value inside the range is shown as before
    scores[0] = s("ball", "local", 0.5, unc=0.039, dof=3, bias=0.384)
    (t,) = effect_tables(scores, INFO)
    ref = t["rows"][0]["cells"][0]
    assert not ref["correction_fails"] and ref["corrected"] == pytest.approx(0.5 - 0.384)
    # every metric of the tables has the smallest value the report assumes
    from pbrbench.metrics import METRICS

    assert {m.lower for m in METRICS.values()} == {METRIC_LOWER_BOUND}


def test_paired_jackknife_of_many_groups():
    from pbrbench.uncertainty import paired

    loc = s("x", "local", 1.0, unc=0.5, rep=(1.5, 0.5, 1.4, 0.6))
    glo = s("x", "global", 2.0, unc=0.5, rep=(2.51, 1.49, 2.42, 1.58))
    se, dof = paired(glo, loc)
    d = [0.01, -0.01, 0.02, -0.02]
    assert dof == 3 and se == pytest.approx(math.sqrt(3 / 4 * sum(x * x for x in d)))


def test_scene_classes_make_one_row_group_each_in_sort_order_with_values_beside_the_cost():
    # two classes whose single mean would blur them: a bright room where the cost is large and a dark one
    scores = [s("white", "local", 0.1), s("white", "global", 0.7), s("black", "local", 0.2),
              s("black", "global", 0.22), s("g[a=1]", "local", 0.0), s("g[a=1]", "global", 0.3),
              s("h[a=1]", "local", 0.0), s("h[a=1]", "global", 0.5), s("stray", "local", 1.0),
              s("stray", "global", 1.0)]
    labels = {"white": (2, "white room"), "black": (1, "black room"), "g[a=1]": (0, "grooves"),
              "h[a=1]": (3, "grooves")}
    layout = {"t": {"scene_class": labels.get, "values": ("global",)}}
    (t,) = effect_tables(scores, INFO, geometry={"g[a=1]": "concave", "white": "convex"}, layout=layout)
    assert [g["label"] for g in t["groups"]] == ["grooves", "black room", "white room", "other scenes"]
    assert t["groups"][0]["scenes"] == ["g[a=1]", "h[a=1]"]   # a class spans families: sorted with its first
    assert [c["label"] for c in t["columns"]] == ["local", "global − local", "global"]   # no geometry split
    cells = {r["group"]: r["cells"] for r in t["rows"]}
    assert [r["group"] for r in t["rows"]] == ["grooves", "black room", "white room", "other scenes"]
    assert cells["white room"][1]["value"] == pytest.approx(0.6) and cells["white room"][1]["n"] == 1
    assert cells["black room"][1]["value"] == pytest.approx(0.02)
    assert cells["grooves"][1]["value"] == pytest.approx(0.4) and cells["grooves"][1]["n"] == 2
    assert cells["grooves"][1]["se"] == pytest.approx(math.sqrt(2 * 0.1 ** 2 * 2) / 2)
    assert cells["white room"][2]["value"] == pytest.approx(0.7) and not cells["white room"][2]["effect"]
    assert cells["grooves"][1]["scenes"] == ["g[a=1]", "h[a=1]"]
    # without a layout: one ungrouped table, as before
    (t,) = effect_tables(scores, INFO)
    assert t["groups"] == [] and {r["group"] for r in t["rows"]} == {None} and len(t["rows"]) == 1


def test_a_row_over_fewer_scenes_is_flagged_and_given_beside_the_others_on_its_scenes():
    # "few" is scored under the reference on the hard cup only: its local mean (2.0) is below m's over
    # both scenes (3.0) but above m's on the cup (1.5); the row says so and is not coloured against m
    from pbrbench.report.html import headline_tables

    scores = [s("cup", "local", 1.5), s("cup", "global", 9.0), s("ball", "local", 4.5), s("ball", "global", 5.0),
              s("cup", "local", 2.0, alg="few"), s("cup", "global", 3.0, alg="few"),
              s("cup", "local", 0.5, alg="n"), s("ball", "local", 0.5, alg="n")]
    (t,) = effect_tables(scores, INFO)
    rows = {r["algorithm"]: r for r in t["rows"]}
    assert rows["few"]["subset"] == (1, 2) and rows["m"]["subset"] is None
    lines = {p["condition"]: p for p in t["partial"] if p["algorithm"] == "few"}
    assert set(lines) == {"local", "global"} and (lines["local"]["ref_n"], lines["local"]["of"]) == (1, 2)
    assert lines["local"]["value"] == pytest.approx(2.0)
    assert [(b["algorithm"], b["value"]) for b in lines["local"]["beside"]] == [("m", pytest.approx(1.5)),
                                                                                ("n", pytest.approx(0.5))]
    assert [(b["algorithm"], b["value"]) for b in lines["global"]["beside"]] == [("m", pytest.approx(9.0))]
    (h,) = headline_tables(scores, INFO)
    cells = {r["algorithm"]: r["cells"][0] for r in h["rows"]}
    assert cells["few"]["colour"] is None and "1 of the 2 scenes" in cells["few"]["title"]
    assert cells["m"]["colour"] is not None and cells["n"]["colour"] is not None


def test_the_console_summary_labels_a_row_over_fewer_scenes():
    from types import SimpleNamespace

    from pbrbench.cli.run import summary_lines

    scores = [s("cup", "local", 1.5), s("ball", "local", 4.5), s("cup", "local", 2.0, alg="few")]
    lines = summary_lines(SimpleNamespace(scores=scores, task_info=INFO))
    assert any(line.strip().startswith("few (1 of 2 scenes)") for line in lines)
    assert not any(line.strip().startswith("m (") for line in lines)
    assert "its row's means are over its own scenes" in lines[-1]


def test_a_chaotic_score_carries_no_bias_and_its_cell_says_so():
    # a chaotic score's replicates are independent draws: their mean minus the value is no bias, so
    # the cell is not noise-limited (its jackknife "bias" here would be 3 x 2.0 = 6 > SE), and it
    # counts the chaotic scores (the report's tooltip names them)
    rep = [18.0, 14.0, 19.0, 13.0]
    scores = [s("cup", "local", 1.0, rep=[1.0, 1.0, 1.0, 1.0], dof=3, bias=0.0),
              s("cup", "global", 10.0, unc=1.4, rep=rep, dof=4, bias=float("nan"), chaotic=True)]
    (t,) = effect_tables(scores, INFO)
    ref, eff = t["rows"][0]["cells"]
    assert ref["chaotic"] == 0 and eff["chaotic"] == 1
    assert not eff["noise_limited"] and math.isnan(eff["bias"])
    assert eff["se"] == pytest.approx(math.hypot(1.4, 0.1))   # not paired: the two SEs in quadrature
    plain = dict(scores[1], chaotic=None)
    (t,) = effect_tables([scores[0], plain], INFO)
    assert t["rows"][0]["cells"][1]["noise_limited"]   # the same replicates read as a jackknife: "biased"
