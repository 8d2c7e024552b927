"""Proof that the ground-truth renders are right: closed-form and statistical checks.

Each check renders (through the render cache) small validation scenes built from SceneSpec
dicts, compares them with an exact answer from :mod:`pbrbench.shading.irradiance` or with a
second, independent render, and returns records
``{"check", "measured", "bound", "passed", "detail"}``.  The checks:

1. ``sphere_directional``, ``sphere_point``: a Lambertian sphere against the box-filtered analytic
   image ``rho E max(0, N.S) / pi`` and ``rho I cos / (pi r^2)``; relative error on fully covered
   interior pixels.
2. ``area_source``: the receiving plane of ``shadow_near`` without its occluder against Lambert's
   formula for the polygonal source (error relative to the peak); ``penumbra``: the profile across
   the shadow against the exact irradiance of the visible part of the source; ``shadow_edges``:
   umbra and penumbra boundaries where the source projected through the occluder's edges puts them.
3. ``integrating_sphere``: inside a closed Lambertian sphere with a point source at the centre,
   ``L = L_direct / (1 - rho)`` for rho = 0.3, 0.6, 0.9.
4. ``normals``: AOV normals of the sphere against the analytic normals (degrees); ``depth``: depth
   of a tilted plane against the analytic plane.
5. ``decomposition``: direct + indirect of one render against the global radiance of an
   independent render (another seed), per-pixel t-test; ``light_sum``: the per-light images sum
   to the all-lights render, per-pixel t-test.  For these records ``measured`` is the number of
   pixel tests rejected at a family-wise alpha of 0.01 (Bonferroni) and ``bound`` is 0.
6. Interreflection (:mod:`.interreflection`, :mod:`.cap`,
   :mod:`.gain`): ``radiosity_groove``, ``radiosity_room``, ``radiosity_cap`` (the
   radiosity model and the concave cap's closed form, with photometric stereo, against the path
   tracer) and ``gain_curve`` (the kernel integral against Mitsuba's irradiance meter).

The validation scenes state their ``standard`` settings; ``quality`` scales them as for the
library (draft: resolution / 4 with at least 32 px, spp / 16), and each bound holds at draft.
"""

from __future__ import annotations

from collections.abc import Callable

from pbrbench.quality import Quality, require
from pbrbench.render.proofs.common import Record, quiet_mitsuba
from pbrbench.render.proofs.direct import (
    check_area_source,
    check_decomposition,
    check_depth,
    check_integrating_sphere,
    check_sphere,
)


# --------------------------------------------------------------------------- registry
def _check_groove(q, c, **kw):
    from pbrbench.render.proofs.interreflection import check_groove

    return check_groove(q, c, figures=kw.get("figures"))


def _check_room(q, c, **kw):
    from pbrbench.render.proofs.interreflection import check_room

    return check_room(q, c, figures=kw.get("figures"))


def _check_cap(q, c, **kw):
    from pbrbench.render.proofs.cap import check_cap

    return check_cap(q, c, figures=kw.get("figures"), photometric_stereo=kw.get("photometric_stereo"))


def _check_gain(q, c, **kw):
    from pbrbench.render.proofs.gain import check_gain_curve

    return check_gain_curve(q, c, figures=kw.get("figures"))


# every check: (quality, cache, *, diagnostics_dir, figures, photometric_stereo) -> records; ``figures``
# (a dict, when given) collects plot dicts, ``photometric_stereo`` is the method the cap check runs
CHECKS: dict[str, Callable[..., list[Record]]] = {
    "sphere_directional": lambda q, c, **kw: check_sphere(q, c, kind="directional"),
    "sphere_point": lambda q, c, **kw: check_sphere(q, c, kind="point"),
    "area_source": lambda q, c, **kw: check_area_source(q, c),
    "integrating_sphere": lambda q, c, **kw: check_integrating_sphere(q, c),
    "depth": lambda q, c, **kw: check_depth(q, c),
    "decomposition": lambda q, c, **kw: check_decomposition(q, c, diagnostics_dir=kw.get("diagnostics_dir")),
    "radiosity_groove": _check_groove,
    "radiosity_room": _check_room,
    "radiosity_cap": _check_cap,
    "gain_curve": _check_gain,
}


def run_checks(quality: Quality, checks, cache, *, progress=None, diagnostics_dir=None,
               figures=None, photometric_stereo=None) -> list[Record]:
    """Run the named checks (default: all) at ``quality``; returns every record.  Statistical
    checks that fail write diagnostic images into ``diagnostics_dir`` when it is given; checks
    with figures add them (name -> plot dict) to ``figures`` when it is given; the cap check runs
    ``photometric_stereo`` (a method of :data:`pbrbench.infer.photometric_stereo.METHODS`, which
    this layer does not import) on its renders."""
    require(quality)
    names = list(CHECKS) if not checks else list(checks)
    unknown = [n for n in names if n not in CHECKS]
    if unknown:
        from pbrbench.errors import UserError

        raise UserError(f"--checks: unknown check(s) {', '.join(unknown)}; choose from {', '.join(CHECKS)}")
    quiet_mitsuba()
    out: list[Record] = []
    for n in names:
        recs = CHECKS[n](quality, cache, diagnostics_dir=diagnostics_dir, figures=figures,
                         photometric_stereo=photometric_stereo)
        out += recs
        if progress is not None:
            progress(n, recs)
    return out
