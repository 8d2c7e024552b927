"""The gain curve of interreflection (chapter Fig 1.19) measured by Mitsuba: the ``gain_curve`` check.

A small patch at unit height above a plane whose radiance is ``L0 (1 + m sin(omega x + phase))``
(an emitting rectangle with a bitmap texture) measures its irradiance with Mitsuba's
``irradiancemeter``; four phases give the complex response ``H`` of the patch and its gain
``|H|`` (:func:`measure_gain_mitsuba`), which the check compares with the kernel integral of
:func:`pbrbench.shading.gain_curve.gain_response` for the same finite plane.  Moved here from
:mod:`pbrbench.shading.gain_curve` (the shading layer does not import the renderer).

Noise: the meter's estimate of ``E = pi mean(L)`` over cosine-sampled directions has
``sd(E) <= pi L0 m / sqrt(spp)`` (``|L - L0| <= L0 m``), so each component of ``H`` (a difference
of two phases over ``2 pi L0 m``) has ``sd <= sqrt(2) / (2 sqrt(spp))``, and so has ``|H|``.  The
texture's bilinear interpolation of the sinusoid (``texels`` over the plane) changes ``H`` by a
relative ``(omega dx)^2 / 8`` at most (``dx`` the texel spacing), the discretisation allowance.

References
----------
J. J. Koenderink and A. J. van Doorn, "Geometrical modes as a general method to treat diffuse
interreflections in radiometry", JOSA 73(6), 1983; D. A. Forsyth and A. Zisserman, "Reflections on
shading", IEEE PAMI 13(7), 1991.
"""

from __future__ import annotations

import numpy as np

from pbrbench.quality import Quality, require
from pbrbench.render.proofs.common import Record, record
from pbrbench.shading.gain_curve import gain_curve, gain_measurement_spec

__all__ = ["gain_mitsuba_dict", "measure_gain_mitsuba", "check_gain_curve", "GAIN_POINTS", "GAIN_SPP"]

GAIN_SPP = 1 << 18                 # samples per phase at standard (scaled by the quality profile)
GAIN_POINTS = ((0.5, 0.0), (1.0, 0.0), (2.0, 0.0), (4.0, 0.0), (1.0, 0.7), (2.0, 0.7), (1.0, 1.4), (2.0, 1.4))


def gain_mitsuba_dict(mi, desc: dict, *, spp: int = 1 << 18) -> dict:
    """The Mitsuba scene dict of :func:`gain_measurement_spec` (direct emission only: ``max_depth = 1``)."""
    T = mi.ScalarTransform4f
    X = desc["plane"]["half_size"]
    tex = np.asarray(desc["plane"]["radiance"], np.float32)
    bmp = np.ascontiguousarray(np.repeat(np.repeat(tex[None, :, None], 2, axis=0), 3, axis=2))
    c, n = desc["patch"]["center"], desc["patch"]["normal"]
    h = desc["patch"]["half_size"]
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 1},
        "plane": {"type": "rectangle", "to_world": T().scale([X, X, 1.0]),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
                  "emitter": {"type": "area", "radiance": {"type": "bitmap", "bitmap": mi.Bitmap(bmp), "raw": True,
                                                             "filter_type": "bilinear", "wrap_mode": "clamp"}}},
        "patch": {"type": "rectangle",
                  "to_world": T().look_at(origin=c.tolist(), target=(c + n).tolist(), up=[0.0, 1.0, 0.0]) @ T().scale([h, h, 1.0]),
                  "sensor": {"type": "irradiancemeter",
                             "film": {"type": "hdrfilm", "width": 1, "height": 1, "pixel_format": "rgb",
                                      "component_format": "float32", "rfilter": {"type": "box"}},
                             "sampler": {"type": "independent", "sample_count": int(spp)}}},
    }


def measure_gain_mitsuba(omega: float, slant: float, *, spp: int = 1 << 18, seed: int = 0, **kw) -> dict:
    """Render the four phases 0, pi/2, pi, 3 pi/2 and recover the gain from the irradiance differences.

    ``E(0) - E(pi) = 2 pi L0 m Im H`` and ``E(pi/2) - E(3pi/2) = 2 pi L0 m Re H``.  Returns the
    measured and the expected (finite-plane) gain and the four irradiances.  Imports Mitsuba
    through :func:`pbrbench.render.variant.mitsuba`.
    """
    from pbrbench.render.variant import mitsuba

    mi = mitsuba()
    E, exp = [], []
    for k, ph in enumerate((0.0, np.pi / 2, np.pi, 1.5 * np.pi)):
        desc = gain_measurement_spec(omega, slant, phase=ph, **kw)
        scene = mi.load_dict(gain_mitsuba_dict(mi, desc, spp=spp))
        img = np.array(mi.render(scene, seed=seed + k), dtype=float)
        E.append(float(img.reshape(-1, img.shape[-1])[0, :3].mean()))
        exp.append(desc["expected_irradiance"])
        del scene
    L0, m = desc["mean_radiance"], desc["modulation"]
    im = (E[0] - E[2]) / (2 * np.pi * L0 * m)
    re = (E[1] - E[3]) / (2 * np.pi * L0 * m)
    return {"gain": float(np.hypot(re, im)), "expected_gain": float(abs(desc["H"])), "irradiance": np.array(E),
            "expected_irradiance": np.array(exp), "response": complex(re, im), "expected_response": desc["H"]}


def check_gain_curve(quality: Quality, cache, *, figures=None, points=None, seed: int = 0) -> list[Record]:
    """``gain_curve``: Mitsuba's measured gain against the kernel integral at (omega, slant) points
    (:data:`GAIN_POINTS` at every quality: a point costs about 0.2 s), ``GAIN_SPP`` samples per
    phase scaled like a render's."""
    from scipy.stats import norm

    from pbrbench.shading.gain_curve import gain_response

    q = require(quality)
    pts = tuple(points) if points is not None else GAIN_POINTS
    spp = q.spp(GAIN_SPP)
    sd = np.sqrt(2) / (2 * np.sqrt(spp))
    z = float(norm.isf(0.01 / (2 * len(pts))))
    rows, worst, worst_rel = [], 0.0, 0.0
    for w, s in pts:
        r = measure_gain_mitsuba(w, s, spp=spp, seed=seed)
        desc = gain_measurement_spec(w, s)
        dx = 2 * desc["plane"]["half_size"] / len(desc["plane"]["texture_x"])
        disc = r["expected_gain"] * (w * dx) ** 2 / 8
        worst = max(worst, abs(r["gain"] - r["expected_gain"]) / (z * sd + disc))
        worst_rel = max(worst_rel, abs(r["gain"] / r["expected_gain"] - 1))
        rows.append((w, s, r["gain"], r["expected_gain"], abs(gain_response(w, s))))
    detail = (f"max |G_mitsuba - G_kernel| / (z sd + d) over {len(pts)} (omega, slant) points; sd(G) <= {sd:.2g} "
              f"({spp} samples per phase, 4 phases), z = {z:.2f}, texel discretisation d <= (omega dx)^2/8 relative; "
              f"largest relative difference {100 * worst_rel:.2f} %; "
              + "; ".join(f"omega {w:g} slant {s:g}: {g:.4f} vs {e:.4f}" for w, s, g, e, _ in rows))
    out = [record("gain_curve", worst, 1.0, detail)]
    if figures is not None:
        om = np.linspace(0.0, 6.0, 61)
        slants = sorted({s for _, s, *_ in rows} | {0.0, 0.7, 1.4})
        G = gain_curve(om, slants)
        series = {}
        for k, s in enumerate(slants):
            col = f"C{k}"
            series[f"kernel, slant {np.degrees(s):.0f} deg"] = {"x": om.tolist(), "y": G[k].tolist(), "color": col,
                                                               "marker": ""}
            pts_s = [(w, g) for w, ss, g, *_ in rows if ss == s]
            if pts_s:
                series[f"Mitsuba, slant {np.degrees(s):.0f} deg"] = {
                    "x": [p[0] for p in pts_s], "y": [p[1] for p in pts_s], "color": col, "marker": "o", "linestyle": ""}
        figures["gain_curve: kernel integral vs Mitsuba irradiance meter"] = {
            "x": None, "series": series, "xlabel": "spatial frequency omega (patch at unit height)",
            "ylabel": "gain |H(omega, slant)|", "title": "gain of interreflection: kernel integral and Mitsuba (Fig 1.19)"}
    return out
