"""Speed and accuracy of retinex and specularity removal on analytic scenes (no renderer).

``python -m pbrbench.perf.lightness [--quick]`` prints a table; :func:`run` returns the rows.

Cases
-----
- timing: 1024x1024 grey retinex (target <= 0.5 s), the same with a disc mask (masked Poisson).
- Mondrian under a smooth point-source light: LMSE (Grosse et al. 2009, MIT variant), largest
  patch-ratio error, si-MSE, for the chapter's algorithm (``edge_illumination="keep"``) and
  the corrected one (``"subtract"``), grey and colour.
- anchor rules side by side: absolute albedo error of "brightest is white" and "mean" when the
  brightest paper is white (1.0) and when it is 0.8.
- cast shadow: the shadow edge is taken for paint (the known failure).
- glossy sphere (Lambert + Blinn-Phong lobe): specular-mask IoU vs the diffuse-only twin and
  removal error inside / around the mask, for two lobe widths and both fill methods.
"""

from __future__ import annotations

import time

import numpy as np

from pbrbench.infer.lightness import retinex
from pbrbench.infer.specular import detect_specularities, remove_specularities
from pbrbench.metrics.lightness import albedo_abs_error, intrinsic_lmse, ratio_errors, si_mse
from pbrbench.metrics.specular import mask_iou, removal_errors, specular_mask_from_twin
from pbrbench.perf import main_for, row
from pbrbench.shading.lambert import blinn_phong_highlights
from pbrbench.shading.mondrian import mondrian_albedo, mondrian_scene, point_source_shading
from pbrbench.shading.surfaces import on_grid

__all__ = ["glossy_sphere", "run", "main"]


def glossy_sphere(size: int = 256, *, light=(0.4, 0.5, 0.77), shininess: float = 80.0,
                  specular: float = 0.6, albedo=(0.7, 0.5, 0.3), ambient: float = 0.05):
    """A sphere under a distant light, Lambert + Blinn-Phong (Blinn, SIGGRAPH 1977), in NumPy.

    ``I = rho (max(0, N.L) + ambient) + k_s max(0, N.H)^n [N.L > 0]`` with ``H`` the unit
    half-vector of ``L`` and the view ``V = (0, 0, 1)``; the specular lobe is white.

    Returns ``(image, diffuse_only, mask)``: (size, size, 3) images and the sphere mask.
    """
    s = on_grid("sphere", size, half_width=1.1)
    n = s.normals
    lv = np.asarray(light, float)
    lv = lv / np.linalg.norm(lv)
    nl = np.maximum(n @ lv, 0.0)
    m = s.mask[..., None]
    diffuse = (nl[..., None] + ambient) * np.asarray(albedo, float) * m
    spec = specular * blinn_phong_highlights(n, lv, shininess, mask=s.mask)[0][..., None] * np.ones(3)
    return diffuse + spec, diffuse, s.mask


def _row(case, method, metric, value, unit="", *, better="lower"):
    """A row of this benchmark: errors and times (lower is better) unless ``better`` says otherwise."""
    return row("lightness", case, method, metric, value, unit, better=better)


def _time(fn, repeat):
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def run(quick: bool = False) -> list[dict]:
    rows: list[dict] = []
    repeat = 1 if quick else 3
    # --- timing ------------------------------------------------------------------------------
    big = 512 if quick else 1024
    scene = mondrian_scene(big, seed=0)
    img = scene["image"]
    rows.append(_row(f"mondrian {big}x{big} grey", "retinex", "time",
                     _time(lambda: retinex(img), repeat), "s"))
    yy, xx = np.mgrid[0:big, 0:big]
    disc = (xx - big / 2 + 0.5) ** 2 + (yy - big / 2 + 0.5) ** 2 <= (0.45 * big) ** 2
    rows.append(_row(f"mondrian {big}x{big} grey, disc mask", "retinex", "time",
                     _time(lambda: retinex(img, mask=disc), repeat), "s"))

    # --- accuracy on analytic Mondrians -----------------------------------------------------------
    size = 256
    for colour in (False, True):
        sc = mondrian_scene(size, seed=1, colour=colour)
        kind = "colour" if colour else "grey"
        for ei in ("keep", "subtract"):
            r, s = retinex(sc["image"], edge_illumination=ei)
            meth = f"retinex edge_illumination={ei}"
            case = f"mondrian {kind}, point light"
            rows.append(_row(case, meth, "LMSE", intrinsic_lmse(r, s, sc["albedo"], sc["shading"])))
            rows.append(_row(case, meth, "max ratio error",
                             np.nanmax(np.abs(ratio_errors(r, sc["albedo"], sc["labels"]))), "fraction"))
            rows.append(_row(case, meth, "si-MSE reflectance", si_mse(r, sc["albedo"])))

    # the chapter's algorithm under a gentler light: the leak is proportional to the light's
    # per-pixel log gradient (about 1 % per edge crossed at 0.01 / pixel)
    for sz in (256, 512):
        alb, lab = mondrian_albedo(sz, seed=1)
        sh = point_source_shading(sz, position=(0.3, 0.2, 3.0))
        r, s = retinex(alb * sh)
        case = f"mondrian grey {sz}, far point light (h=3)"
        rows.append(_row(case, "retinex edge_illumination=keep", "LMSE", intrinsic_lmse(r, s, alb, sh)))
        rows.append(_row(case, "retinex edge_illumination=keep", "max ratio error",
                         np.nanmax(np.abs(ratio_errors(r, alb, lab))), "fraction"))

    # --- anchor rules --------------------------------------------------------------------------------
    for white in (1.0, 0.8):
        sc = mondrian_scene(size, seed=2, white_patch=white, albedo_range=(0.1, min(white, 0.8)))
        for anchor in ("brightest", "mean"):
            r, _ = retinex(sc["image"], anchor=anchor, mean_lightness=float(sc["albedo"].mean())
                           if anchor == "mean" else 0.5, edge_illumination="subtract")
            rows.append(_row(f"mondrian brightest paper {white}", f"anchor={anchor}"
                             + (" (true mean)" if anchor == "mean" else ""),
                             "albedo abs error", albedo_abs_error(r, sc["albedo"])))
        r, _ = retinex(sc["image"], anchor="mean", mean_lightness=0.5, edge_illumination="subtract")
        rows.append(_row(f"mondrian brightest paper {white}", "anchor=mean (0.5)",
                         "albedo abs error", albedo_abs_error(r, sc["albedo"])))

    # --- cast shadow: the known failure -------------------------------------------------------------
    for shadow in (False, True):
        sc = mondrian_scene(size, seed=1, shadow=shadow)
        for ei in ("keep", "subtract"):
            r, s = retinex(sc["image"], edge_illumination=ei)
            case = "mondrian grey, cast shadow" if shadow else "mondrian grey, no shadow"
            meth = f"retinex edge_illumination={ei}"
            rows.append(_row(case, meth, "LMSE", intrinsic_lmse(r, s, sc["albedo"], sc["shading"])))
            rows.append(_row(case, meth, "max ratio error",
                             np.nanmax(np.abs(ratio_errors(r, sc["albedo"], sc["labels"]))), "fraction"))

    # --- specularities -------------------------------------------------------------------------------
    for shin in (80.0, 300.0):
        image, diffuse, _ = glossy_sphere(256, shininess=shin)
        truth = specular_mask_from_twin(image, diffuse, threshold=0.1)
        case = f"glossy sphere 256, Blinn-Phong n={shin:g}"
        t = time.perf_counter()
        det = detect_specularities(image)
        rows.append(_row(case, "detect_specularities", "time", time.perf_counter() - t, "s"))
        rows.append(_row(case, "detect_specularities", "mask IoU (twin, 10% of peak)",
                         mask_iou(det, truth)))
        base = removal_errors(image, diffuse, truth)
        rows.append(_row(case, "no removal", "inside rel. RMSE", base["inside_rel"]))
        for method in ("harmonic", "biharmonic"):
            out = remove_specularities(image, det, method=method)
            err = removal_errors(out, diffuse, truth)
            rows.append(_row(case, f"remove {method}", "inside rel. RMSE", err["inside_rel"]))
            rows.append(_row(case, f"remove {method}", "ring rel. RMSE", err["ring_rel"]))
    return rows


def main(argv=None) -> None:
    main_for(run, argv)


if __name__ == "__main__":
    main()
