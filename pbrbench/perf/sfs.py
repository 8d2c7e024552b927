"""Shape from one shaded image: every method on analytic surfaces, beside the flat baseline and the
floor (the methods of :mod:`pbrbench.infer.sfs`).

Cases: {sphere, vase} x light {frontal (0,0,1) [sphere only], oblique (1,0,1)/sqrt 2} x
{known light, light estimated by ``light_from_shading``} x noise {0, 1 % of the peak}, at
256 x 256 (``quick``: 96 x 96).  Per case and method: height RMSE (offset removed, world units),
height RMSE relative to the object's half width, mean normal angle, ambiguity-aware angle,
seconds; per case: the flat baseline and the floor.

Run: ``python -m pbrbench.perf.sfs`` (add ``--quick`` for the small grid).
"""

from __future__ import annotations

import sys
import warnings

import numpy as np

from pbrbench.infer.sfs import METHODS, light_from_shading, shape_from_shading
from pbrbench.metrics.sfs import flat_baseline, floor_scores, sfs_scores
from pbrbench.perf import row
from pbrbench.shading.lambert import lambertian_images
from pbrbench.shading.surfaces import on_grid

HALF_WIDTH = 1.1
ALBEDO = 0.8
LIGHTS = {"frontal": np.array([0.0, 0.0, 1.0]), "oblique": np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)}


def _cases(quick: bool):
    for surface in ("sphere", "vase"):
        for lname in ("frontal", "oblique"):
            if surface == "vase" and lname == "frontal":
                continue
            for known in (True, False):
                for noise in (0.0, 0.01):
                    if quick and (noise > 0 or not known) and lname == "frontal":
                        continue
                    yield surface, lname, known, noise


def run(quick: bool = False) -> list[dict]:
    n = 96 if quick else 256
    h = 2 * HALF_WIDTH / n
    rows: list[dict] = []

    def add(case, method, metric, value, unit):
        rows.append(row("sfs", case, method, metric, value, unit, better="lower"))   # errors, seconds, warnings

    for surface, lname, known, noise in _cases(quick):
        s = on_grid(surface, n, half_width=HALF_WIDTH)
        m = s.mask
        light = LIGHTS[lname]
        img = lambertian_images(s.normals, ALBEDO, light[None])[0]
        if noise > 0:
            rng = np.random.default_rng(0)
            img = np.clip(img + noise * img[m].max() * rng.standard_normal(img.shape), 0.0, None)
        img = np.where(m, img, 0.0)
        zt = np.where(m, s.z, 0.0)
        case = f"{surface}/{lname}/{'known' if known else 'estimated'}-light/noise{noise:g}/{n}px"
        if known:
            lt, alb = light, ALBEDO
        else:
            est = light_from_shading(img, m)
            lt, alb = est.direction, est.albedo
            add(case, "light_from_shading", "light_angle",
                np.degrees(np.arccos(np.clip(lt @ light, -1, 1))), "deg")
        radius = 1.0 if surface == "sphere" else 0.65  # the vase's largest profile radius ~ 0.65
        flat = flat_baseline(zt, s.normals, m)
        floor = floor_scores(zt, s.normals, m, pixel_size=h)
        for ref, sc in (("flat", flat), ("floor", floor)):
            add(case, ref, "height_rmse", sc["rmse"], "world")
            add(case, ref, "normal_angle", sc["normal_angle"], "deg")
        for method in METHODS:
            with warnings.catch_warnings(record=True) as w:
                warnings.simplefilter("always")
                res = shape_from_shading(img, lt, method=method, albedo=alb, mask=m, pixel_size=h)
            sc = sfs_scores(res.height, res.normals, zt, s.normals, m)
            add(case, method, "height_rmse", sc["rmse"], "world")
            add(case, method, "height_rmse_rel", 100 * sc["rmse"] / radius, "% radius")
            add(case, method, "height_rmse_scaled", sc["rmse_scaled"], "world")
            add(case, method, "normal_angle", sc["normal_angle"], "deg")
            add(case, method, "normal_angle_ambiguous", sc["normal_angle_ambiguous"], "deg")
            add(case, method, "seconds", res.seconds, "s")
            add(case, method, "warnings", len(w), "count")
    return rows


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    rows = run(quick="--quick" in argv)
    cases = list(dict.fromkeys(r["case"] for r in rows))
    cols = ["height_rmse", "height_rmse_rel", "normal_angle", "normal_angle_ambiguous", "seconds", "light_angle"]
    for case in cases:
        print(case)
        sub = [r for r in rows if r["case"] == case]
        for method in dict.fromkeys(r["method"] for r in sub):
            vals = {r["metric"]: r["value"] for r in sub if r["method"] == method}
            cells = "  ".join(f"{c}={vals[c]:.4g}" for c in cols if c in vals)
            print(f"  {method:18s} {cells}")


if __name__ == "__main__":
    main()
