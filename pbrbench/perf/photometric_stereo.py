"""Speed and accuracy of photometric stereo and surface integration on analytic inputs.

``python -m pbrbench.perf.photometric_stereo [--quick]`` prints a table; :func:`run` returns rows.

Cases
-----
- timing: Woodham photometric stereo, 1024x1024, 12 lights, shadow handling on, sphere mask
  (target <= 0.5 s); ``lsq`` integration 1024x1024 over a non-rectangular mask (target <= 2 s);
  the shared Poisson solver on the full square (DCT, target <= 0.3 s) and on a mask (<= 2 s).
  Each timing is reported as the best wall-clock time of a few repeats and as the process CPU
  time of that call (the CPU time is the fairer number on a loaded machine).
- integration accuracy: the four methods over a non-rectangular (notched) mask on the ``bumps``
  and ``random_smooth`` surfaces, plus the sphere and the vase (whose silhouette slopes are
  infinite); height RMSE after the free offset, in % of the height range (target: lsq < 1 %).
- sphere angular error, the chapter's 5 lights (one along the view, four at (+-1, 0, 1.5),
  (0, +-1, 1.5) normalised): noise-free (target < 0.01 deg on pixels lit by >= 3 lights) and the
  naive fit that keeps shadowed zeros; 8-bit quantised (target < 0.2 deg); Gaussian noise of
  0, 0.5, 1, 2 % of the brightest pixel, Woodham and the robust L1 method.
- highlights: a Lambert + Blinn-Phong sphere under 12 lights, Woodham vs the robust L1 method.
- robust: spheres and bumps, K = 20 random lights, Blinn-Phong highlights (n = 60), occluders
  darkening discs of each image to 10-50 % (cast-shadow-like outliers) and Gaussian noise of
  0.2 %: every method of :data:`pbrbench.infer.photometric_stereo.METHODS` (Woodham, L1,
  sparse Bayesian learning, low-rank recovery), angular error and time at 256 x 256 (128 with
  ``--quick``).  No photometric-stereo peer is on PyPI, so there are no peer rows here.
"""

from __future__ import annotations

import time

import numpy as np

from pbrbench.infer.integration import METHODS as INTEGRATION_METHODS
from pbrbench.infer.integration import integrate_normals
from pbrbench.infer.photometric_stereo import solve_photometric_stereo
from pbrbench.infer.poisson import solve_gradient_field
from pbrbench.metrics.normals import angular_error_stats, height_rmse
from pbrbench.perf import main_for, row
from pbrbench.shading.lambert import blinn_phong_highlights, lambertian_images, ring_lights
from pbrbench.shading.surfaces import on_grid, pixel_grid

__all__ = ["CHAPTER_LIGHTS", "ring_lights", "notched_mask", "run", "main"]

CHAPTER_LIGHTS = np.array([[0, 0, 1], [1, 0, 1.5], [-1, 0, 1.5], [0, 1, 1.5], [0, -1, 1.5]], float)
CHAPTER_LIGHTS /= np.linalg.norm(CHAPTER_LIGHTS, axis=1, keepdims=True)


def notched_mask(size: int, half_width: float = 1.0) -> np.ndarray:
    """A non-convex domain: an ellipse plus a disc, minus a notch cut in from the right."""
    x, y = pixel_grid(size, size, half_width)
    blob = ((x / 0.9) ** 2 + (y / 0.7) ** 2 < 1) | ((x - 0.3) ** 2 + (y + 0.5) ** 2 < 0.2)
    return blob & ~((x > 0.2) & (np.abs(y) < 0.15))


def _row(case, method, metric, value, unit=""):
    """A row of this benchmark; its direction from :data:`BETTER` (every metric it reports)."""
    return row("photometric_stereo", case, method, metric, value, unit, better=BETTER[metric])


BETTER = {"time_wall": "lower", "time_cpu": "lower", "height_rmse_pct_range": "lower", "valid_fraction": "higher",
          "mean_angular_error": "lower", "median_angular_error": "lower", "albedo_mean_abs_error": "lower"}


def _timed(fn, repeats):
    best_wall, cpu, out = np.inf, np.inf, None
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        wall, c = time.perf_counter() - t0, time.process_time() - c0
        if wall < best_wall:
            best_wall, cpu = wall, c
    return best_wall, cpu, out


def _timing_rows(size, repeats):
    rows = []
    case = f"{size}x{size} K=12 sphere mask, shadows on (target <= 0.5 s)"
    s = on_grid("sphere", size, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    wall, cpu, res = _timed(lambda: solve_photometric_stereo(imgs, lights, mask=s.mask), repeats)
    rows += [_row(case, "woodham1980", "time_wall", wall, "s"), _row(case, "woodham1980", "time_cpu", cpu, "s"),
             _row(case, "woodham1980", "mean_angular_error",
                  angular_error_stats(res.normals, s.normals, s.mask & res.valid)["mean"], "deg")]

    b = on_grid("bumps", size, 1.0)
    m = b.mask & notched_mask(size)
    h = 2.0 / size
    case = f"{size}x{size} bumps, notched mask (target <= 2 s)"
    wall, cpu, z = _timed(lambda: integrate_normals(b.normals, mask=m, method="lsq", pixel_size=h), repeats)
    rel = 100 * height_rmse(z, b.z, m) / np.ptp(b.z[m])
    rows += [_row(case, "lsq", "time_wall", wall, "s"), _row(case, "lsq", "time_cpu", cpu, "s"),
             _row(case, "lsq", "height_rmse_pct_range", rel, "%")]

    rng = np.random.default_rng(0)
    gx, gy = rng.normal(size=(2, size, size))
    case = f"{size}x{size} poisson full square (target <= 0.3 s)"
    wall, cpu, _ = _timed(lambda: solve_gradient_field(gx, gy, method="dct"), repeats)
    rows += [_row(case, "dct", "time_wall", wall, "s"), _row(case, "dct", "time_cpu", cpu, "s")]
    x, y = pixel_grid(size, size, 1.0)
    disc = x**2 + y**2 < 0.9
    case = f"{size}x{size} poisson disc mask (target <= 2 s)"
    wall, cpu, _ = _timed(lambda: solve_gradient_field(gx, gy, mask=disc, method="cg"), repeats)
    rows += [_row(case, "cg", "time_wall", wall, "s"), _row(case, "cg", "time_cpu", cpu, "s")]
    return rows


def _integration_rows(size):
    rows = []
    for name, hw, notch in (("bumps", 1.0, True), ("random_smooth", 1.0, True),
                            ("sphere", 1.05, False), ("vase", 1.0, False)):
        s = on_grid(name, size, hw)
        m = s.mask & notched_mask(size, hw) if notch else s.mask
        case = f"{name} {size}x{size} {'notched mask' if notch else 'silhouette mask'}"
        for method in INTEGRATION_METHODS:
            z = integrate_normals(s.normals, mask=m, method=method, pixel_size=2 * hw / size)
            rows.append(_row(case, method, "height_rmse_pct_range",
                             100 * height_rmse(z, s.z, m) / np.ptp(s.z[m]), "%"))
    return rows


def _sphere_rows(size):
    rows = []
    s = on_grid("sphere", size, half_width=1.05)
    n, m = s.normals, s.mask
    lit3 = m & ((n @ CHAPTER_LIGHTS.T > 0).sum(-1) >= 3)
    imgs = lambertian_images(n, 0.8, CHAPTER_LIGHTS, mask=m)
    case = f"sphere {size}x{size}, chapter's 5 lights, noise-free, lit by >= 3 (target < 0.01 deg)"
    r = solve_photometric_stereo(imgs, CHAPTER_LIGHTS, mask=m)
    rows.append(_row(case, "woodham1980", "mean_angular_error",
                     angular_error_stats(r.normals, n, lit3 & r.valid)["mean"], "deg"))
    rows.append(_row(case, "woodham1980", "valid_fraction", (lit3 & r.valid).sum() / lit3.sum()))
    g = np.linalg.lstsq(CHAPTER_LIGHTS, imgs[:, lit3], rcond=None)[0].T
    naive = np.zeros_like(n)
    naive[lit3] = g / np.linalg.norm(g, axis=1, keepdims=True)
    rows.append(_row(case, "naive_all_lights", "mean_angular_error",
                     angular_error_stats(naive, n, lit3)["mean"], "deg"))

    q = np.round(imgs / imgs.max() * 255.0)
    case = f"sphere {size}x{size}, chapter's 5 lights, 8-bit quantised (target < 0.2 deg)"
    r = solve_photometric_stereo(q, CHAPTER_LIGHTS, mask=m, saturation=255.5)
    rows.append(_row(case, "woodham1980", "mean_angular_error",
                     angular_error_stats(r.normals, n, lit3 & r.valid)["mean"], "deg"))

    rng = np.random.default_rng(0)
    for pct in (0.0, 0.5, 1.0, 2.0):
        noisy = imgs + rng.normal(scale=pct / 100 * imgs.max(), size=imgs.shape)
        case = f"sphere {size}x{size}, chapter's 5 lights, Gaussian noise {pct:g} % of max"
        for method in ("woodham1980", "ikehata2012_l1"):
            r = solve_photometric_stereo(noisy, CHAPTER_LIGHTS, mask=m, method=method)
            st = angular_error_stats(r.normals, n, lit3 & r.valid)
            rows += [_row(case, method, "mean_angular_error", st["mean"], "deg"),
                     _row(case, method, "median_angular_error", st["median"], "deg"),
                     _row(case, method, "valid_fraction", (lit3 & r.valid).sum() / lit3.sum())]
    return rows


def _highlight_rows(size, shininess=300.0):
    s = on_grid("sphere", size, half_width=1.05)
    lights = ring_lights(12)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    spec = blinn_phong_highlights(s.normals, lights, shininess, mask=s.mask)
    hl = (spec > 1e-3).any(0) & s.mask
    rows = []
    case = f"glossy sphere {size}x{size}, K=12, Blinn-Phong n={shininess:g}, highlight pixels"
    for method in ("woodham1980", "ikehata2012_l1"):
        wall, cpu, r = _timed(lambda method=method: solve_photometric_stereo(imgs + spec, lights, mask=s.mask,
                                                                       method=method), 1)
        st = angular_error_stats(r.normals, s.normals, hl & r.valid)
        rows += [_row(case, method, "mean_angular_error", st["mean"], "deg"),
                 _row(case, method, "albedo_mean_abs_error", np.abs(r.albedo[hl & r.valid] - 0.8).mean()),
                 _row(case, method, "time_cpu", cpu, "s")]
    return rows


def robust_stack(surface: str, size: int, k: int, *, seed: int = 0):
    """``(images, normals, lights, mask)``: a Lambert + Blinn-Phong surface under ``k`` random
    lights (elevation 25-70 deg) with occluder discs (each image darkened to 10-50 % inside a
    random disc, cast-shadow-like) and Gaussian noise of 0.002; ``mask``: pixels lit by >= 3."""
    rng = np.random.default_rng(seed)
    el = np.radians(rng.uniform(25, 70, k))
    az = np.radians(rng.uniform(0, 360, k))
    lights = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    s = on_grid(surface, size, half_width=1.05 if surface == "sphere" else 1.0)
    imgs = lambertian_images(s.normals, 0.8, lights, mask=s.mask)
    imgs += 0.8 * blinn_phong_highlights(s.normals, lights, 60.0, mask=s.mask)
    yy, xx = np.mgrid[0:size, 0:size]
    for i in range(k):
        cy, cx = rng.uniform(0, size, 2)
        r = rng.uniform(0.05, 0.15) * size
        imgs[i][(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] *= rng.uniform(0.1, 0.5)
    imgs = np.maximum(imgs + rng.normal(0, 0.002, imgs.shape), 0.0)
    mask = s.mask & ((s.normals @ lights.T > 0).sum(-1) >= 3)
    return imgs, s.normals, lights, mask


def _robust_rows(size):
    from pbrbench.infer.photometric_stereo import METHODS

    rows = []
    for surface in ("sphere", "bumps"):
        imgs, normals, lights, mask = robust_stack(surface, size, 20)
        case = f"{surface} {size}x{size}, K=20, highlights + occluders + 0.2 % noise"
        for method in METHODS:
            wall, cpu, r = _timed(lambda method=method, i=imgs, li=lights, m=mask: solve_photometric_stereo(
                i, li, mask=m, method=method), 1)
            st = angular_error_stats(r.normals, normals, mask & r.valid)
            rows += [_row(case, method, "mean_angular_error", st["mean"], "deg"),
                     _row(case, method, "median_angular_error", st["median"], "deg"),
                     _row(case, method, "valid_fraction", (mask & r.valid).sum() / mask.sum()),
                     _row(case, method, "time_wall", wall, "s"), _row(case, method, "time_cpu", cpu, "s")]
    return rows


def run(quick: bool = False) -> list[dict]:
    """All cases; ``quick`` shrinks the images (256 instead of 1024 for the timings)."""
    rows = _timing_rows(256 if quick else 1024, 2 if quick else 3)
    rows += _integration_rows(128 if quick else 256)
    rows += _sphere_rows(128 if quick else 256)
    rows += _highlight_rows(64 if quick else 128)
    rows += _robust_rows(128 if quick else 256)
    return rows


def main(argv=None) -> None:
    main_for(run, argv)


if __name__ == "__main__":
    main()
