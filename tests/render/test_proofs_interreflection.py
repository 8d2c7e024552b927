"""The interreflection checks of `pbrbench validate` at draft quality, through the render cache: the
radiosity model against the path tracer (groove, rooms), the concave cap's closed form against the
renderer, the ring-mesh solver and Woodham photometric stereo, and the gain curve against Mitsuba's
irradiance meter; plus the comparison machinery on synthetic cells and its failure mode."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.quality import DRAFT
from pbrbench.render import proofs
from pbrbench.render.cache import RenderCache
from pbrbench.render.proofs import interreflection as IR

RECORD_KEYS = {"check", "measured", "bound", "passed", "detail"}


@pytest.fixture(scope="module")
def cache(cache_dir):
    return RenderCache(cache_dir)


def _all_pass(records):
    bad = [f"{r['check']}: {r['measured']:.3g} > {r['bound']:.3g} ({r['detail']})" for r in records if not r["passed"]]
    assert not bad, "\n".join(bad)
    assert all(set(r) == RECORD_KEYS for r in records)


def _woodham():
    from pbrbench.infer.photometric_stereo import METHODS

    return METHODS["woodham1980"]


# ------------------------------------------------------------------------ machinery, no renders
def _synthetic(rng, n_cells=20, px=30, sd=0.01, bias=0.0):
    ids = np.repeat(np.arange(n_cells), px).reshape(n_cells, px)
    truth = np.linspace(0.2, 1.0, n_cells)[:, None] * np.ones((1, px))
    render = truth + rng.normal(0, sd, truth.shape)
    delta = rng.normal(0, sd, truth.shape)  # a half-difference has the image's sd
    cells = IR.Cells.of(ids, np.ones(ids.shape, bool), render, delta, n_cells)

    def model_at(level):  # converges at first order toward truth * (1 + bias)
        return truth * (1 + bias) + 0.08 / level

    return cells, model_at


def test_refinement_stops_when_converged_and_agrees_within_noise():
    cells, model_at = _synthetic(np.random.default_rng(1))
    c = IR.refine(lambda lev: cells, model_at, [1, 2, 4, 8, 16])
    assert c.levels[-1] < 16  # stopped once d and the excess were within 2 % of the peak
    assert np.max(c.d) <= 0.02 * c.peak and c.excess() <= 0.02
    assert c.agreement() <= 1.0
    # the standard errors are the sd of a 30-pixel mean
    assert np.median(cells.se) == pytest.approx(0.01 / np.sqrt(30), rel=0.3)


def test_a_biased_model_fails():
    """Failure mode: a model 5 % too bright is outside the noise and the discretisation error."""
    cells, model_at = _synthetic(np.random.default_rng(2), bias=0.05)
    c = IR.refine(lambda lev: cells, model_at, [1, 2, 4, 8, 16, 32, 64])
    recs = IR._records("synthetic", c, "levels")
    assert [r["passed"] for r in recs] == [False, False]


def test_pooled_noise_guards_cells_whose_half_differences_vanish():
    ids = np.repeat(np.arange(4), 10)
    delta = np.zeros(40)
    delta[:10] = 0.3  # cell 0 noisy; the others show no difference at all (few samples)
    cells = IR.Cells.of(ids, np.ones(40, bool), np.ones(40), delta, 4)
    assert np.all(cells.se[1:] > 0) and cells.se[0] > cells.se[1]


def test_groove_specs_of_other_angles_keep_the_geometry():
    for opening in (60.0, 90.0, 120.0):
        spec = IR.groove_spec(opening, 0.5, "parallel")
        got, w, length = IR.groove_geometry(spec)
        assert got == pytest.approx(opening) and length == 4.0
        assert w * np.sin(np.radians(opening / 2)) == pytest.approx(1.1)
    lib = IR._library("groove_reflex_parallel")[0]
    assert IR.groove_geometry(lib)[0] == pytest.approx(90.0)
    with pytest.raises(ValueError, match="groove"):
        IR.groove_geometry(IR._library("room_white")[0])


def test_unknown_arguments_reach_every_check():
    assert {"radiosity_groove", "radiosity_room", "radiosity_cap", "gain_curve"} <= set(proofs.CHECKS)


# ----------------------------------------------------------------------------- the checks
@pytest.mark.render
def test_radiosity_groove(cache):
    figures = {}
    recs = IR.check_groove(DRAFT, cache, figures=figures)
    _all_pass(recs)
    names = {r["check"] for r in recs}
    assert {"radiosity_groove[parallel,rho=0.9]", "radiosity_groove[bisector,rho=0.9]:peak"} <= names
    assert len(figures) == 2 and all(len(f["series"]) == 6 for f in figures.values())


@pytest.mark.render
@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_radiosity_room_and_the_perspective_index(cache):
    figures = {}
    recs = IR.check_room(DRAFT, cache, figures=figures)
    _all_pass(recs)
    assert {r["check"] for r in recs} == {"radiosity_room[room_black]", "radiosity_room[room_black]:peak",
                                          "radiosity_room[room_white]", "radiosity_room[room_white]:peak"}
    (fig,) = figures.values()
    white = np.array(fig["series"]["room_white: path tracer"]["y"])
    black = np.array(fig["series"]["room_black: path tracer"]["y"])
    local = np.array(fig["series"]["room_white: local model"]["y"])
    assert white.mean() > 1.3 * black.mean()  # the same direct light, far more light in the white room
    assert white.mean() > 1.3 * local.mean()
    # the patch the perspective index image gives contains the pixel's rendered position (position AOV)
    from pbrbench.radiosity.forward_models import model_patches, view_width
    from pbrbench.radiosity.image import patch_index_image

    spec = IR._library("room_white")[0]
    gt = proofs.common.ground_truth_of(spec, DRAFT, cache)
    H, W = gt.mask.shape
    mesh = model_patches(spec, view_width(spec) / 8)
    idx = patch_index_image(spec, mesh, (W, H))
    pure = gt.mask & (idx >= 0)
    P = gt["position"][pure].astype(float)
    k = idx[pure]
    dist = np.abs(np.sum((P - mesh.centres[k]) * mesh.normals[k], axis=1))
    assert np.median(dist) < 1e-3 and np.mean(dist < 0.02) > 0.97


@pytest.mark.render
@pytest.mark.longest   # scheduled first (tests/conftest.py)
def test_radiosity_cap_renderer_solver_and_photometric_stereo(cache):
    figures = {}
    recs = proofs.run_checks(DRAFT, ["radiosity_cap"], cache, figures=figures, photometric_stereo=_woodham())
    _all_pass(recs)
    kinds = {r["check"].split("]")[1] for r in recs}
    assert kinds == {":render", ":render:peak", ":solver", ":photometric_stereo", ":ps_beta"}
    assert {r["check"].split("]")[0] + "]" for r in recs} >= {"radiosity_cap[rho=0.9,alpha=60]", "radiosity_cap[rho=0.7,alpha=40]"}
    beta = next(r for r in recs if r["check"] == "radiosity_cap[rho=0.9,alpha=60]:ps_beta")
    assert "vs the closed form 0.2177" in beta["detail"]
    assert len(figures) == 2


@pytest.mark.render
def test_cap_without_a_photometric_stereo_method_fails_that_record(cache):
    from pbrbench.render.proofs.cap import check_cap

    spec = IR._library("ps_cap")[-1]
    recs = check_cap(DRAFT, cache, specs=[spec])
    ps = next(r for r in recs if r["check"].endswith(":photometric_stereo"))
    assert not ps["passed"] and "no photometric-stereo method" in ps["detail"]


@pytest.mark.render
def test_cap_records_fail_for_a_wrong_albedo(cache):
    """Failure mode: the closed form of another albedo (0.6 instead of 0.9) is refused by the render
    and the beta records."""
    from pbrbench.radiosity.concave_cap import cap_photometric_stereo_bias, cap_radiosity
    from pbrbench.render.proofs import cap as PC
    from pbrbench.scene.geometry import light_vectors
    from pbrbench.shading import surfaces

    spec = IR._library("ps_cap")[-1]
    case = PC.cap_case(spec, DRAFT, cache, photometric_stereo=_woodham())
    H, W = case["interior"].shape
    X, Y = surfaces.pixel_grid(H, W, spec.camera.half_width)
    z = surfaces.evaluate("spherical_cap", X, Y, radius=1.0, half_angle_deg=60.0).z
    L = light_vectors(spec)
    for k, cl in enumerate(case["cells"]):
        S = L[k] / np.linalg.norm(L[k])
        B = cap_radiosity(np.stack([X, Y, z], -1), rho=0.6, half_angle_deg=60.0, direction=S, irradiance=np.linalg.norm(L[k]))
        case["closed"][k] = cl.mean(B / np.pi)
    case["beta"] = cap_photometric_stereo_bias(0.6, 60.0)
    recs = {r["check"].split("]")[1]: r for r in PC._case_records(case)}
    assert not recs[":render"]["passed"] and not recs[":ps_beta"]["passed"]


@pytest.mark.render
def test_gain_curve(cache):
    figures = {}
    recs = proofs.run_checks(DRAFT, ["gain_curve"], cache, figures=figures)
    _all_pass(recs)
    (fig,) = figures.values()
    assert any(k.startswith("Mitsuba") for k in fig["series"])


@pytest.mark.render
def test_the_gallery_gain_figure_has_the_chapters_ten_slants_and_mitsuba_points():
    """Fig 1.19 of the gallery: the kernel integral at slants 0 to 90 degrees in 10 steps (the
    chapter's), and Mitsuba's measured gain at three of them, each point on its curve within the
    meter's noise (sd <= sqrt(2) / (2 sqrt(spp))) plus the finite plane's and the curve's
    sampling (0.01)."""
    from pbrbench.render.proofs.gain import GAIN_SPP
    from pbrbench.shading.gain_curve import gain_curve
    from pbrbench.tasks._interreflection_figures import GAIN_MITSUBA_OMEGAS, _gain_plot

    fig = _gain_plot(DRAFT)
    curves = [k for k in fig["series"] if k.startswith("slant ")]
    assert [int(k.split()[1]) for k in curves] == list(range(0, 91, 10))
    points = {k: v for k, v in fig["series"].items() if "Mitsuba" in k}
    assert len(points) == 3 and sum(not k.startswith("_") for k in points) == 1      # one legend entry
    sd = np.sqrt(2) / (2 * np.sqrt(DRAFT.spp(GAIN_SPP)))
    for v in points.values():
        slant = np.radians(next(int(c.split()[1]) for c in curves if fig["series"][c]["color"] == v["color"]))
        assert v["x"] == list(GAIN_MITSUBA_OMEGAS)
        np.testing.assert_allclose(v["y"], gain_curve(np.array(v["x"]), [slant])[0], atol=5 * sd + 0.01)


@pytest.mark.render
@pytest.mark.slow
def test_mitsuba_measures_the_gain():
    """Four phases rendered with an irradiance meter.

    Cosine-sampled estimate of ``E = pi mean(L)``: ``sd(E) <= pi L0 m / sqrt(spp)`` since
    ``|L - L0| <= L0 m``; each component of ``H`` is a difference of two phases over
    ``2 pi L0 m``, so its sd is at most ``sqrt(2) / (2 sqrt(spp))``.
    """
    from pbrbench.render.proofs.gain import measure_gain_mitsuba

    spp = 1 << 18
    r = measure_gain_mitsuba(1.0, 0.7, spp=spp)  # L0 = 1, m = 0.5 (the defaults)
    sd_E = np.pi * 1.0 * 0.5 / np.sqrt(spp)
    sd_H = np.sqrt(2) / (2 * np.sqrt(spp))
    np.testing.assert_allclose(r["irradiance"], r["expected_irradiance"], atol=5 * sd_E)
    d = r["response"] - r["expected_response"]
    assert abs(d.real) < 5 * sd_H and abs(d.imag) < 5 * sd_H
    assert r["gain"] == pytest.approx(r["expected_gain"], abs=10 * sd_H)


@pytest.mark.render
def test_validate_command_prints_stores_and_writes_figures(cache_dir, tmp_path, capsys):
    import json

    from pbrbench.bench.store import Store
    from pbrbench.cli.main import main

    rc = main(["validate", "--quality", "draft", "--checks", "gain_curve", "--cache", str(cache_dir),
               "--store", str(tmp_path / "h.sqlite"), "--out", str(tmp_path / "v")])
    out = capsys.readouterr()
    assert rc == 0 and "gain_curve" in out.out and "pass" in out.out
    with Store(tmp_path / "h.sqlite") as store:
        run = store.resolve_run("latest")
        rows = store.scores(run, task="validate")
        assert store.get_run(run)["config"]["validate_quality"] == "draft"
    assert {(r["scene"], r["metric"]) for r in rows} == {("gain_curve", m) for m in ("measured", "bound", "passed")}
    assert next(r for r in rows if r["metric"] == "passed")["value"] == 1.0
    folder = tmp_path / "v"
    rec = json.loads((folder / "records.json").read_text())
    assert rec["run"] == run and rec["records"][0]["check"] == "gain_curve"
    pngs = list(folder.glob("*.png"))
    assert len(pngs) == 1 and pngs[0].read_bytes()[:4] == b"\x89PNG"
    assert pngs[0].name in (folder / "index.html").read_text()
