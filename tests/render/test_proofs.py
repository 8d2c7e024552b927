"""Proof that the ground truth is right (`pbrbench validate`), at draft quality, through the render cache.

Each test renders small validation scenes (pbrbench.render.proofs) and asserts every record meets its
bound: closed forms (Lambert's law on a sphere, Lambert's formula for a polygonal source, the
integrating sphere, analytic normals and depth) and statistical comparisons of independent renders.
"""

from __future__ import annotations

import pytest

from pbrbench.quality import DRAFT
from pbrbench.render import proofs as V
from pbrbench.render.cache import RenderCache
from pbrbench.render.proofs import direct as D
from pbrbench.render.proofs.common import ground_truth_of


@pytest.fixture(scope="module")
def cache(cache_dir):
    return RenderCache(cache_dir)


def _assert_all(records, expected):
    names = {r["check"] for r in records}
    assert expected <= names, f"missing records {expected - names}"
    bad = [f"{r['check']}: {r['measured']:.3g} > {r['bound']:.3g} ({r['detail']})" for r in records if not r["passed"]]
    assert not bad, "\n".join(bad)
    for r in records:
        assert set(r) == {"check", "measured", "bound", "passed", "detail"}


@pytest.mark.render
def test_sphere_directional_and_normals(cache):
    recs = D.check_sphere(DRAFT, cache, kind="directional")
    _assert_all(recs, {"sphere_directional", "normals"})
    assert next(r for r in recs if r["check"] == "sphere_directional")["bound"] == 1e-3


@pytest.mark.render
def test_sphere_point_light(cache):
    _assert_all(D.check_sphere(DRAFT, cache, kind="point"), {"sphere_point"})


@pytest.mark.render
def test_area_source_penumbra_and_edges(cache):
    recs = D.check_area_source(DRAFT, cache)
    _assert_all(recs, {"area_source", "penumbra", "shadow_edges"})
    bounds = {r["check"]: r["bound"] for r in recs}
    assert bounds["area_source"] == 0.01 and bounds["penumbra"] == 0.02


@pytest.mark.render
def test_integrating_sphere(cache):
    recs = D.check_integrating_sphere(DRAFT, cache)
    _assert_all(recs, {"integrating_sphere[rho=0.3]", "integrating_sphere[rho=0.6]", "integrating_sphere[rho=0.9]"})
    assert all(r["bound"] == 0.01 for r in recs)


@pytest.mark.render
def test_depth_of_a_tilted_plane(cache):
    _assert_all(D.check_depth(DRAFT, cache), {"depth", "normals_plane"})


@pytest.mark.render
def test_decomposition_and_light_sum(cache, tmp_path):
    _assert_all(D.check_decomposition(DRAFT, cache, diagnostics_dir=tmp_path),
                {"decomposition", "light_sum", "light_sum_direct"})


@pytest.mark.render
def test_a_wrong_reference_fails(cache):
    """Failure mode: the same render against a reference with a 1 % wrong irradiance must fail."""
    import numpy as np

    from pbrbench.shading import irradiance as irr

    spec = D.sphere_spec(D.DIR_LIGHT, name="validate_sphere_directional")
    gt = ground_truth_of(spec, DRAFT, cache)
    w, h, _ = D._pixel_size(spec, DRAFT)
    ref = irr.sphere_reference((w, h), D.SPHERE_HW, albedo=1.0, direction=D.DIR_LIGHT["direction"], irradiance=3.0 * 1.01)
    refc = ref.radiance[..., None] * np.asarray(D.SPHERE_ALBEDO)
    inner = D._interior(ref, gt.mask)
    rel = np.abs(gt["radiance"] - refc)[inner] / refc[inner]
    assert rel.max() > 5e-3


def test_unknown_check_is_a_user_error():
    from pbrbench.errors import UserError

    with pytest.raises(UserError, match="--checks"):
        V.run_checks(DRAFT, ["nope"], None)
