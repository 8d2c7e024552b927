"""The interreflection task on synthetic ground truths made by a fine radiosity solution of library
scenes (no renderer): the local model fails in the white room and holds in the black one, bounces
converge, failures are scored, plot jobs draw the chapter's figures."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.radiosity.forward_models import predict_radiance
from pbrbench.registry import Algorithm, Registry
from pbrbench.render.groundtruth import GroundTruth
from pbrbench.scene.load import SceneLibrary
from pbrbench.tasks.base import Job
from pbrbench.tasks.interreflection import TASK
from tests.fakes import run_task, scores_of


def fine_gt(name, res=(32, 24), cells=10):
    """Ground truth from the model itself at a finer mesh: radiance = converged, direct = local."""
    spec = SceneLibrary().spec(name)
    rad = predict_radiance(spec, res, cells=cells).astype(np.float32)
    direct = predict_radiance(spec, res, bounces=0, cells=cells).astype(np.float32)
    mask = (rad.sum(-1) > 0).astype(np.float32)
    return GroundTruth({"radiance": rad, "direct": direct, "mask": mask, "albedo": np.full_like(rad, 0.5),
                        "object_id": mask.astype(np.float32)}, {"scene_hash": spec.content_hash()})


@pytest.fixture(scope="module")
def rooms():
    return {n: fine_gt(n) for n in ("room_black", "room_white")}


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
def test_the_local_model_fails_in_the_white_room_and_holds_in_the_black_one(rooms):
    err = {}
    for name, gt in rooms.items():
        for cond in ("global", "local"):
            sc = scores_of(run_task(TASK, Job(TASK.name, name, cond), {name: gt}))
            err[name, cond] = sc
    white, black = err["room_white", "global"], err["room_black", "global"]
    assert white[("local", "radiosity_rel_error")] > 0.3           # most of the white room's light is interreflected
    assert black[("local", "radiosity_rel_error")] < 0.15          # the black room's is not
    assert white[("radiosity", "radiosity_rel_error")] < 0.5 * white[("local", "radiosity_rel_error")]
    bounces = [white[(a, "radiosity_rel_error")] for a in ("local", "radiosity:1", "radiosity:2", "radiosity:4")]
    assert all(b < a for a, b in zip(bounces, bounces[1:], strict=False))       # each bounce adds the light it missed
    # against the direct light the local model is the right one, the radiosity model adds light
    assert err["room_white", "local"][("local", "radiosity_rel_error")] < err["room_white", "local"][
        ("radiosity", "radiosity_rel_error")]


@pytest.mark.slow   # the rooms fixture takes 7 s to build (per worker)
def test_a_broken_model_is_scored_as_failed(rooms):
    def bad(spec, resolution):
        return np.zeros((3, 3))

    reg = Registry([Algorithm("bad", TASK.name, bad, kind="plugin")])
    res = run_task(TASK, Job(TASK.name, "room_black", "global"), {"room_black": rooms["room_black"]}, registry=reg)
    assert scores_of(res)[("bad", "failed")] == 1.0 and "radiance" in res.failures["bad"]


@pytest.mark.slow   # the rooms fixture takes 7 s to build (per worker)
def test_grey_output_is_accepted(rooms):
    def grey(spec, resolution):
        return predict_radiance(spec, resolution, cells=8).mean(-1)

    reg = Registry([Algorithm("grey", TASK.name, grey, kind="plugin")])
    res = run_task(TASK, Job(TASK.name, "room_white", "global"), {"room_white": rooms["room_white"]}, registry=reg)
    assert scores_of(res)[("grey", "radiosity_rel_error")] < 0.2


@pytest.mark.slow   # the rooms fixture takes 7 s to build (per worker)
def test_room_and_groove_plots_name_their_chapter_figures(rooms):
    res = run_task(TASK, Job(TASK.name, "room_white", "global", (("plot", "rooms"),), ("room_black",)), rooms)
    assert not res.scores and any(k.startswith("Fig 1.17") for k in res.plots)
    (section,) = res.plots.values()
    assert {"white room: path tracer", "black room: radiosity model", "local model (either room)"} <= set(section["series"])
    names = ["groove_reflex_parallel[albedo=0.1]", "groove_reflex_parallel[albedo=0.9]"]
    gts = {n: fine_gt(n, res=(32, 16)) for n in names}
    res = run_task(TASK, Job(TASK.name, names[1], "global", (("plot", "groove"),), (names[0],)), gts)
    assert {k.split(" ")[1] for k in res.plots} == {"1.18", "1.19"}
    prof = next(v for k, v in res.plots.items() if k.startswith("Fig 1.18"))
    hi = np.array(prof["series"]["albedo 0.9: path tracer"]["y"], float)
    lo = np.array(prof["series"]["albedo 0.1: path tracer"]["y"], float)
    assert np.nanmax(hi) > np.nanmax(lo)  # B / albedo grows with albedo: interreflection


def test_jobs_skip_black_scenes_and_draw_every_gallery_figure():
    from pbrbench.quality import get_quality

    jobs = TASK.jobs(get_quality("draft"))
    assert not any("albedo=0]" in j.scene for j in jobs)
    plots = {j.param("plot") for j in jobs} - {None}
    assert plots == {"groove", "rooms", "bump", "bleeding", "shadows"}
    # local is the reference, as in every task: the cost of interreflection is global - local
    assert TASK.reference_condition == "local" and "global − local" in TASK.notes
    assert TASK.headline_values == ("global",)


def test_every_scored_scene_has_a_class_and_grooves_share_one_per_albedo():
    from pbrbench.quality import get_quality

    for q in ("draft", "standard"):
        scenes = {j.scene for j in TASK.jobs(get_quality(q)) if j.param("plot") is None}
        classes = {s: TASK.scene_class(s) for s in scenes}
        assert None not in classes.values(), q
        assert classes["room_white"] == "white room" and classes["room_black"] == "black room"
        grooves = {c for s, c in classes.items() if s.startswith("groove_")}
        albedos = {s.split("=")[1] for s in scenes if s.startswith("groove_")}
        assert grooves == {f"grooves, albedo {a[:-1]}" for a in albedos} and len(grooves) >= 2, q
        assert classes["ps_cap[albedo=0.9]"] == "concave cap, albedo 0.9"
    assert TASK.scene_class("room_white") != TASK.scene_class("room_black")
    assert TASK.scene_class("shadow_near") is None


@pytest.mark.render
def test_fig_1_21_zoom_renders_the_shadow_and_shows_its_reflex():
    """The zoom renders the cast shadow on its own (96 px across -0.75 < x < -0.15, at least 256
    spp at draft): inside the shadow the direct light is 0, the full transport is not (the reflex
    from the lit plane and the bump), and the radiosity model predicts its level within 2x; the
    local model predicts nothing there."""
    from pbrbench.quality import DRAFT
    from pbrbench.tasks._interreflection_figures import _bump_zoom, _cells

    z = _bump_zoom(TASK.scenes.spec("cylinder_bump"), DRAFT, _cells(TASK, DRAFT))
    (pt,) = [v for k, v in z.items() if k.startswith("path tracer (global)")]
    x = np.array(pt["x"])
    assert len(x) == 96 and x.min() < -0.7 and x.max() > -0.2
    lo, hi = -0.48, -0.32          # inside the shadow, and inside the model's draft patches that it covers
    inside = (x > lo) & (x < hi)

    def at(name):
        v = z[name]
        xx = np.array(v["x"])
        y = np.array([np.nan if u is None else u for u in v["y"]])
        return y[(xx > lo) & (xx < hi)]
    glob = np.array(pt["y"])[inside]
    direct = at("path tracer, direct light only")
    assert np.all(direct < 1e-6) and np.all(glob > 1e-3)
    rad, loc = at("radiosity model"), at("local model")
    assert 0.5 < np.mean(glob) / np.mean(rad) < 2.0 and np.all(loc < 1e-6)
