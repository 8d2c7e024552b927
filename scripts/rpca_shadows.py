"""Where the reference RPCA's advantage on the bunny comes from: attached shadows as data.

    python scripts/rpca_shadows.py [--bunny DATA_DIR] [--cache DIR] [SCENE ...]
    python scripts/rpca_shadows.py --lambda-scan [--bunny DATA_DIR] [--stacks] [--factors F ...]

The RobustPhotometricStereo repository's RPCA (docs/peers.md) decomposes the raw observation
matrix ``D`` (K lights x N pixels, shadowed entries 0 and kept as observations) into a low-rank
``A`` and a sparse ``E`` (``min ||A||_* + lambda ||E||_1`` s.t. ``D = A + E``, inexact ALM,
``lambda = 1 / sqrt(max(K, N))``) and takes the normals from the least-squares fit of ``A`` over
every light.  ``wu2010`` follows Wu et al. (2010): shadowed entries are missing (completed, not
fitted), and the normal is the least-squares fit of the lit measurements the recovery and the
Lambertian fit do not flag.  This script implements the first design here (with ``wu2010``'s own
inexact ALM, every entry observed; no code of that repository) and prints its mean normal error beside
``woodham1980`` and ``wu2010``:

- on the bunny sets of that repository (``--bunny``: its ``data/bunny`` folder; see
  ``scripts/rps_bunny.py``), over the mask;
- on the benchmark's standard renders (``SCENE``; default five photometric-stereo scenes), in
  the task's evaluation domain, conditions ``local``, ``global`` and ``local+noise0.01`` (render
  seed 0; a scene missing from ``--cache`` is rendered).

``--lambda-scan`` asks a second question: is ``lambda`` what keeps ``wu2010`` above the reference?
It takes the normals from the low-rank matrix of Wu et al.'s own design (shadowed entries
missing, ``wu2010``'s recovery) at ``lambda`` = F / sqrt(max(K, N)) for each factor F, and prints
the mean error and the rank of ``A`` beside ``wu2010`` on the bunny sets and (``--stacks``) on the
robust stacks of ``pbrbench perf photometric_stereo`` (sphere, bumps, vase; 8, 12, 20, 40
lights; capture seeds 0, 1; 128 x 128).

Nothing is fetched.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

SCENES = ["sphere_12lights", "sphere_5lights", "sphere_textured", "ps_bumps[albedo=0.9]", "ps_groove[albedo=0.9]"]


def rpca_all(D: np.ndarray, n_iter: int = 1000, tol: float = 1e-6):
    """``(A, E, rank)``: robust PCA of every entry of ``D`` (wu2010's inexact ALM with every entry
    observed, ``lambda = 1 / sqrt(max(K, N))``)."""
    from pbrbench.infer.photometric_stereo.wu2010 import inexact_alm

    return inexact_alm(D, np.ones(D.shape, bool), 1.0 / np.sqrt(max(D.shape)), n_iter, tol)


def normals_from_lowrank(images: np.ndarray, lights: np.ndarray, mask: np.ndarray):
    """(H, W, 3) unit normals (0 outside ``mask``) and the rank of the recovered matrix."""
    s = lights / np.linalg.norm(lights, axis=1, keepdims=True)
    A, _, rank = rpca_all(images[:, mask])
    n = np.zeros(mask.shape + (3,))
    n[mask] = np.linalg.lstsq(s, A, rcond=None)[0].T
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12), rank


def mean_error_deg(n: np.ndarray, gt: np.ndarray) -> float:
    """Mean angle in degrees between unit normals ``n`` and ``gt`` (both (P, 3))."""
    return float(np.degrees(np.arccos(np.clip(np.einsum("pc,pc->p", n, gt), -1, 1))).mean())


def bunny_sets(data_dir: str):
    """``(name, images, lights, mask, normals)`` of the two bunny sets with shadows
    (``scripts/rps_bunny.py``'s loader)."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from rps_bunny import load

    return [(name, *load(data_dir, name)) for name in ("bunny_lambert", "bunny_specular")]


def normals_from_completion(images, lights, mask, factor: float):
    """(P, 3) unit normals over ``mask`` from the low-rank matrix of Wu et al.'s design (entries
    below ``wu2010``'s shadow threshold missing) at ``lambda = factor / sqrt(max(K, N))``, and
    its rank."""
    from pbrbench.infer.photometric_stereo._common import measurements, prepare
    from pbrbench.infer.photometric_stereo.wu2010 import inexact_alm

    p = prepare(images, lights, mask, None, 0.01, None, 3)
    jsum, used, _ = measurements(p)
    A, _, rank = inexact_alm(np.where(used, jsum, 0.0), used, factor / np.sqrt(max(jsum.shape)), 1000, 1e-7)
    g = np.linalg.lstsq(p.s, A, rcond=None)[0].T
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-300), rank


def lambda_scan(data_dir, stacks: bool, factors) -> None:
    from pbrbench.infer.photometric_stereo import METHODS

    cases = bunny_sets(data_dir) if data_dir else []
    if stacks:
        from pbrbench.perf.photometric_stereo import robust_stack

        for surface in ("sphere", "bumps", "vase"):
            for k in (8, 12, 20, 40):
                for seed in (0, 1):
                    imgs, gt, lights, mask = robust_stack(surface, 128, k, seed=seed)
                    cases.append((f"{surface} K={k} seed {seed}", imgs, lights, mask, gt))
    print("case                      wu2010  " + "  ".join(f"x{f:<4g} (rank)" for f in factors))
    for name, imgs, lights, mask, gt in cases:
        r = METHODS["wu2010"](imgs, lights, mask=mask)
        row = [f"{mean_error_deg(r.normals[mask], gt[mask]):6.2f}"]
        for f in factors:
            n, rank = normals_from_completion(imgs, lights, mask, f)
            row.append(f"{mean_error_deg(n, gt[mask]):6.2f} ({rank:2d})")
        print(f"{name:24s} " + "  ".join(row), flush=True)


def bunny(data_dir: str) -> None:
    from pbrbench.infer.photometric_stereo import METHODS

    for name, imgs, lights, mask, gt in bunny_sets(data_dir):
        n, rank = normals_from_lowrank(imgs, lights, mask)
        row = [f"shadows as data {mean_error_deg(n[mask], gt[mask]):6.3f} (rank {rank})"]
        for a in ("woodham1980", "wu2010"):
            r = METHODS[a](imgs, lights, mask=mask)
            row.append(f"{a} {mean_error_deg(np.where(r.valid[..., None], r.normals, 0.0)[mask], gt[mask]):6.3f}")
        print(f"{name:24s} " + "  ".join(row), flush=True)


def renders(scenes, cache) -> None:
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # the helper beside this script
    from _ps_inputs import ps_inputs

    from pbrbench.infer.photometric_stereo import METHODS
    from pbrbench.metrics.normals import normal_scores

    for name, cond, images, lights, mask, domain, n_true in ps_inputs(scenes, cache):
        grey = images if images.ndim == 3 else images.mean(-1)
        n, rank = normals_from_lowrank(grey, lights, mask)
        ok = mask & (np.linalg.norm(n, axis=-1) > 0)
        row = [f"shadows as data {normal_scores(n, n_true, domain, ok)[0]['normal_mean_deg']:6.2f} (rank {rank})"]
        for a in ("woodham1980", "wu2010"):
            r = METHODS[a](images, lights, mask=mask)
            row.append(f"{a} {normal_scores(r.normals, n_true, domain, r.valid)[0]['normal_mean_deg']:6.2f}")
        print(f"{name:22s} {cond:16s} " + "  ".join(row), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--bunny", help="the RobustPhotometricStereo repository's data/bunny folder")
    ap.add_argument("--cache", default=None, help="render cache (default: pbrbench's)")
    ap.add_argument("--lambda-scan", action="store_true", help="normals from the completed low-rank matrix per lambda")
    ap.add_argument("--stacks", action="store_true", help="with --lambda-scan: the robust stacks of perf")
    ap.add_argument("--factors", nargs="+", type=float, default=[0.4, 0.5, 0.6, 1.0, 2.0])
    a = ap.parse_args(argv)
    if a.lambda_scan:
        lambda_scan(a.bunny, a.stacks, a.factors)
        return 0
    if a.bunny:
        bunny(a.bunny)
    if a.scenes:
        renders(a.scenes, a.cache)
    return 0


if __name__ == "__main__":
    sys.exit(main())
