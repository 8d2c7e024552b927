"""The concave-cap check of ``pbrbench validate`` (``radiosity_cap``): renderer, solver and photometric
stereo against the closed form of :mod:`pbrbench.radiosity.concave_cap`.

Inside a sphere the interreflection kernel is constant, so under distant sources within
``90 - alpha`` of the axis ``a`` the radiosity of a cap of half-angle ``alpha`` is

.. math::  B = \\rho E_0 (N + \\beta a) \\cdot S, \\qquad
           \\beta = \\frac{\\rho \\sin^2\\alpha}{4 (1 - \\rho (1 - \\cos\\alpha) / 2)},

and least-squares photometric stereo on the per-light radiance ``L = B / pi`` recovers
``h = pi g = rho (N + beta a)``: normals tilted toward the axis, albedo ``rho |N + beta a|``.
Records per cap (``rho``, ``alpha``):

* ``...:render`` and ``...:render:peak`` -- each light's rendered radiance against the closed form,
  means over the cells of a 4-ring mesh of the cap (interior pixels: pure, and 2 pixels inside the
  rim), as in :mod:`pbrbench.render.proofs.interreflection` (noise ``z se``; the discretisation
  allowance is the rendered mesh's: the heightfield grid drops the cells cut by the rim, a
  fraction ``delta`` of the cap's area, which lowers the interreflected term
  ``U = rho f E-bar / (1 - rho f)`` by about ``delta U / (1 - rho f)``);
* ``...:solver`` -- the ring mesh's radiosity solution (no visibility: exact inside a sphere),
  its interreflected part ``B - E`` against ``U``, refined (4, 8, 16 rings) until within 2 % of
  the peak of ``B``;
* ``...:photometric_stereo`` -- the method passed in (``pbrbench validate`` passes Woodham's
  least squares) on the rendered per-light radiance: cell means of ``h = pi albedo normal``
  against ``rho (N + beta a)``, with the noise propagated exactly through the least-squares
  solve ``g = (L^T L)^-1 L^T I`` (linear in the images) and the mesh allowance
  ``rho beta delta / (1 - rho f)`` on the axial component;
* ``...:ps_beta`` -- ``beta`` fitted to the recovered ``h`` (``h = c1 N + c2 a`` by least squares
  over the interior, ``beta = c2 / c1``) against the closed form, with its propagated noise.

References
----------
D. A. Forsyth and A. Zisserman, "Reflections on shading", IEEE PAMI 13(7), 1991; R. J. Woodham,
"Photometric method for determining surface orientation from multiple images", Optical
Engineering 19(1), 1980; J. J. Koenderink and A. J. van Doorn, "Geometrical modes as a general
method to treat diffuse interreflections in radiometry", JOSA 73(6), 1983.
"""

from __future__ import annotations

import math

import numpy as np

from pbrbench.quality import Quality, require
from pbrbench.render.proofs.common import Record, ground_truth_of, record
from pbrbench.render.proofs.interreflection import MAX_EXCESS, Cells, _grey, _library, _z, cap_spec

__all__ = ["check_cap", "cap_case", "cap_cases", "mesh_area_deficit"]

CMP_RINGS = (2, 4)    # rings of the comparison cells: below 64 px across, and from 64 px
SOLVER_RINGS = (4, 8, 16)


def mesh_area_deficit(spec) -> float:
    """``delta``: the fraction of the cap's area that the rendered heightfield mesh lacks."""
    from pbrbench.scene.mitsuba_dict import heightfield_mesh

    s = spec.shapes[0]
    v, _, _, f = heightfield_mesh(s, spec.data_root)
    t = v[f]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
    R = float(s.params.get("radius", 1.0))
    a = math.radians(float(s.params.get("half_angle_deg", 60.0)))
    return float(1.0 - area / (2 * math.pi * R * R * (1 - math.cos(a))))


def cap_cases(quality: Quality) -> list:
    """The caps checked at ``quality``: ``ps_cap`` at the albedos the profile keeps, and caps of
    other half-angles (40 and 75 degrees; one in a short profile)."""
    q = require(quality)
    lib = q.keep(_library("ps_cap"))
    extra = q.pick([(0.5, 40.0), (0.9, 40.0), (0.5, 75.0), (0.9, 75.0)], [(0.7, 40.0)])
    return lib + [cap_spec(r, a) for r, a in extra]


def _geometry(spec):
    s = spec.shapes[0]
    if s.type != "heightfield" or s.surface != "spherical_cap" or len(spec.shapes) != 1:
        raise ValueError(f"{spec.name}: a cap scene has one heightfield with surface 'spherical_cap'")
    R = float(s.params.get("radius", 1.0))
    alpha = float(s.params.get("half_angle_deg", 60.0))
    rho = float(np.mean(spec.material_of(s).albedo))
    return R, alpha, rho


def cap_case(spec, quality: Quality, cache, *, photometric_stereo=None) -> dict:
    """Everything the cap records need for one cap (render, closed form, solver, photometric stereo)."""
    from pbrbench.radiosity.concave_cap import (
        cap_form_factor,
        cap_mean_direct,
        cap_photometric_stereo_bias,
        cap_radiosity,
        cap_shadow_free,
        spherical_cap_patches,
    )
    from pbrbench.radiosity.image import patch_index_image
    from pbrbench.scene.geometry import light_vectors
    from pbrbench.shading import surfaces

    R, alpha, rho = _geometry(spec)
    gt = ground_truth_of(spec, quality, cache)
    H, W = gt["radiance"].shape[:2]
    X, Y = surfaces.pixel_grid(H, W, spec.camera.half_width)
    surf = surfaces.evaluate("spherical_cap", X, Y, radius=R, half_angle_deg=alpha)
    px = 2 * spec.camera.half_width / W
    interior = gt.mask & surf.mask & (np.hypot(X, Y) < R * math.sin(math.radians(alpha)) - 2 * px)
    pts = np.stack([X, Y, surf.z], -1)
    lights = light_vectors(spec)
    S = lights / np.linalg.norm(lights, axis=1, keepdims=True)
    E0 = np.linalg.norm(lights, axis=1)
    if not all(cap_shadow_free(s, alpha) for s in S):
        raise ValueError(f"{spec.name}: every source must lie within 90 - alpha of the axis (no shadows)")
    f = cap_form_factor(alpha)
    beta = cap_photometric_stereo_bias(rho, alpha)
    delta = mesh_area_deficit(spec)
    ring = spherical_cap_patches(R, alpha, n_rings=CMP_RINGS[W >= 64])
    ids = patch_index_image(spec, ring, (W, H))
    K = len(S)
    closed = np.stack([cap_radiosity(pts, rho=rho, half_angle_deg=alpha, direction=S[k], irradiance=E0[k]) / np.pi
                       for k in range(K)])
    U = np.array([rho * f * cap_mean_direct(rho, alpha, S[k], E0[k]) / (1 - rho * f) for k in range(K)]) / np.pi
    cells = [Cells.of(ids, interior, gt[f"light{k:02d}.radiance"], gt.sd_of(f"light{k:02d}.radiance", _grey), len(ring))
             for k in range(K)]
    out = {"rings": CMP_RINGS[W >= 64], "spec": spec, "rho": rho, "alpha": alpha, "beta": beta, "delta": delta, "f": f, "cells": cells,
           "closed": [c.mean(closed[k]) for k, c in enumerate(cells)], "U": U, "interior": interior,
           "N": surf.normals, "r": np.hypot(X, Y), "peak": float(closed[:, interior].max()) if interior.any() else 1.0}
    out["solver"] = _solver(R, alpha, rho, S[0], E0[0])
    if photometric_stereo is not None:
        out["ps"] = _photometric_stereo(gt, lights, interior, ids, len(ring), photometric_stereo, rho, beta, surf.normals)
    return out


def _solver(R, alpha, rho, S, E0) -> dict:
    from pbrbench.radiosity.concave_cap import (
        cap_form_factor,
        cap_mean_direct,
        spherical_cap_patches,
    )
    from pbrbench.radiosity.form_factor_matrix import form_factor_matrix
    from pbrbench.radiosity.solver import solve_radiosity

    f = cap_form_factor(alpha)
    U = rho * f * cap_mean_direct(rho, alpha, S, E0) / (1 - rho * f)
    gamma = math.degrees(math.acos(min(1.0, float(S[2]))))   # the source's angle from the axis
    peak = rho * E0 * math.cos(math.radians(max(0.0, gamma - alpha))) + U   # max of B: where N is nearest to S
    err = None
    for n in SOLVER_RINGS:
        p = spherical_cap_patches(R, alpha, n_rings=n, albedo=rho)
        E = rho * E0 * np.maximum(p.normals @ S, 0.0)
        B = solve_radiosity(form_factor_matrix(p, visibility=False), rho, E, method="direct").B
        err = float(np.max(np.abs((B - E) - U)) / peak)
        if err <= MAX_EXCESS:
            break
    return {"rings": n, "patches": len(p), "error": err, "U": U, "peak": peak}


def _photometric_stereo(gt, lights, interior, ids, n_cells, method, rho, beta, N) -> dict:
    """Cell means of ``h = pi albedo normal`` (recovered and closed form), their propagated
    standard errors, and the fitted ``beta`` with its standard error."""
    K = len(lights)
    images = np.stack([_grey(gt[f"light{k:02d}.radiance"]) for k in range(K)])
    sd = np.stack([gt.sd_of(f"light{k:02d}.radiance", _grey) for k in range(K)])
    res = method(images, lights, mask=interior)
    n = np.asarray(getattr(res, "normals", None) if not isinstance(res, dict) else res["normals"], float)
    alb = np.asarray(getattr(res, "albedo", None) if not isinstance(res, dict) else res["albedo"], float)
    alb = alb.mean(-1) if alb.ndim == 3 else alb
    h_rec = np.pi * alb[..., None] * n
    axis = np.array([0.0, 0.0, 1.0])
    h_cf = rho * (N + beta * axis)
    M = np.linalg.pinv(lights)                           # (3, K): the least-squares solve
    var_h = np.pi ** 2 * np.einsum("jk,khw->hwj", M ** 2, sd ** 2)   # per-pixel variance of each component
    sel = interior & (ids >= 0)
    idx = ids[sel]
    cnt = np.maximum(np.bincount(idx, minlength=n_cells).astype(float), 1)

    def cmean(a):
        return np.stack([np.bincount(idx, a[sel][:, j], minlength=n_cells) / cnt for j in range(3)], -1)

    rec, cf = cmean(h_rec), cmean(h_cf)
    # the cell's own variance sum, or the pooled one (mean over the cap) when larger (see Cells)
    vs = var_h[sel]
    own = np.stack([np.bincount(idx, vs[:, j], minlength=n_cells) for j in range(3)], -1)
    se = np.sqrt(np.maximum(own, vs.mean(axis=0) * cnt[:, None])) / cnt[:, None]
    used = np.bincount(idx, minlength=n_cells) >= 4
    # beta by least squares: h = c1 N + c2 a over the interior pixels
    Np, hp = N[sel], h_rec[sel]
    G = np.array([[np.sum(Np * Np), np.sum(Np[:, 2])], [np.sum(Np[:, 2]), float(len(Np))]])
    rhs = np.array([np.sum(Np * hp), np.sum(hp[:, 2])])
    c1, c2 = np.linalg.solve(G, rhs)
    cov_h = np.pi ** 2 * np.einsum("jk,lk,pk->pjl", M, M, sd[:, sel].T ** 2)    # (P, 3, 3)
    Bp = np.stack([Np, np.broadcast_to(axis, Np.shape)], 1)                     # (P, 2, 3)
    var_rhs = np.einsum("pij,pjl,pml->im", Bp, cov_h, Bp)
    Gi = np.linalg.inv(G)
    var_c = Gi @ var_rhs @ Gi
    jac = np.array([-c2 / c1 ** 2, 1.0 / c1])
    beta_fit, beta_se = c2 / c1, float(np.sqrt(max(jac @ var_c @ jac, 0.0)))
    def angle(a, b):
        a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-300)
        b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-300)
        return np.degrees(np.arccos(np.clip(np.sum(a * b, -1), -1, 1)))

    def polar(v):
        return np.degrees(np.arctan2(np.hypot(v[..., 0], v[..., 1]), v[..., 2]))

    ang = angle(rec[used], cf[used])                      # between the cells' mean vectors
    tilt = (polar(N) - polar(h_rec))[sel]                 # signed tilt toward the axis (first-order unbiased)
    tilt_cf = (polar(N) - polar(h_cf))[sel]
    alb_ratio = np.linalg.norm(h_rec[sel], axis=-1) / np.linalg.norm(h_cf[sel], axis=-1)   # pi albedo / rho |N + beta a|
    return {"rec": rec, "cf": cf, "se": se, "used": used, "beta_fit": float(beta_fit), "beta_se": beta_se,
            "rho_fit": float(c1), "angle_mean": float(ang.mean()), "tilt_mean": float(tilt.mean()),
            "tilt_cf_mean": float(tilt_cf.mean()), "albedo_ratio_median": float(np.median(alb_ratio)),
            "h_rec": h_rec, "h_cf": h_cf, "sel": sel}


def _case_records(c: dict) -> list[Record]:
    name = f"radiosity_cap[rho={c['rho']:g},alpha={c['alpha']:g}]"
    rho, f, delta = c["rho"], c["f"], c["delta"]
    K = len(c["cells"])
    m = sum(int(cl.used.sum()) for cl in c["cells"])
    z = _z(m)
    ratio, excess, big = 0.0, 0.0, 0.0
    for k, cl in enumerate(c["cells"]):
        u = cl.used
        d = delta * c["U"][k] / (1 - rho * f)
        diff = np.abs(cl.render - c["closed"][k])[u]
        ratio = max(ratio, float(np.max(diff / (z * cl.se[u] + d))))
        excess = max(excess, float(np.max(np.maximum(diff - z * cl.se[u], 0.0)) / c["peak"]))
        big = max(big, float(np.max(diff)) / c["peak"])
    noise = max(float(np.max(z * cl.se[cl.used])) for cl in c["cells"]) / c["peak"]
    disc = delta * float(np.max(c["U"])) / (1 - rho * f) / c["peak"]
    tail = (f"{K} lights x {c['rings']}-ring cells ({m} compared); noise z*se <= {100 * noise:.2f} % of the peak "
            f"(z = {z:.2f}); mesh allowance (rendered grid lacks {100 * delta:.2f} % of the area) "
            f"{100 * disc:.2f} % of the peak; largest |render - closed form| {100 * big:.2f} % of the peak {c['peak']:.4g}")
    out = [record(f"{name}:render", ratio, 1.0, "max |render - closed form| / (z se + d), per light and cell; " + tail),
           record(f"{name}:render:peak", excess, MAX_EXCESS, "max (|render - closed form| - z se)_+ / peak; " + tail)]
    s = c["solver"]
    out.append(record(f"{name}:solver", s["error"], MAX_EXCESS,
                    f"ring-mesh solution: max |(B - E) - U| / peak with U = rho f E-bar / (1 - rho f) = {s['U']:.4g} "
                    f"(light 0), {s['rings']} rings ({s['patches']} patches), peak B {s['peak']:.4g}"))
    ps = c.get("ps")
    if ps is None:
        out.append(record(f"{name}:photometric_stereo", float("inf"), 1.0,
                        "no photometric-stereo method given (pbrbench validate passes Woodham's least squares)",
                        passed=False))
        return out
    u = ps["used"]
    zz = _z(3 * int(u.sum()))
    d = np.zeros(3)
    d[2] = rho * c["beta"] * delta / (1 - rho * f)
    r = np.abs(ps["rec"] - ps["cf"])[u] / (zz * ps["se"][u] + d + 1e-300)
    out.append(record(f"{name}:photometric_stereo", float(r.max()), 1.0,
                    f"cell means of h = pi albedo normal vs rho (N + beta a), max |diff| / (z se + d) over {int(u.sum())} "
                    f"cells x 3 components (z = {zz:.2f}; se propagated through the least-squares solve; axial mesh "
                    f"allowance {d[2]:.2g}); mean angle between the cells' recovered and closed-form h {ps['angle_mean']:.3f} "
                    f"deg; mean tilt toward the axis {ps['tilt_mean']:.2f} deg (closed form {ps['tilt_cf_mean']:.2f}); median "
                    f"recovered / closed-form albedo {ps['albedo_ratio_median']:.4f}"))
    db = c["beta"] * delta / (1 - rho * f)
    zb = _z(1)
    out.append(record(f"{name}:ps_beta", abs(ps["beta_fit"] - c["beta"]) / (zb * ps["beta_se"] + db + 1e-300), 1.0,
                    f"beta fitted to the recovered h (h = c1 N + c2 a): {ps['beta_fit']:.4f} +- {ps['beta_se']:.1g} vs the "
                    f"closed form {c['beta']:.4f} (mesh allowance {db:.2g}, z = {zb:.2f}); fitted albedo "
                    f"{ps['rho_fit']:.4f} vs {rho:g}"))
    return out


def check_cap(quality: Quality, cache, *, figures=None, specs=None, photometric_stereo=None) -> list[Record]:
    """``radiosity_cap``: the caps of :func:`cap_cases` (or ``specs``)."""
    specs = cap_cases(quality) if specs is None else list(specs)
    cases = [cap_case(s, quality, cache, photometric_stereo=photometric_stereo) for s in specs]
    out = []
    for c in cases:
        out += _case_records(c)
    if figures is not None and cases:
        figures.update(_figures(cases))
    return out


def _figures(cases) -> dict:
    bins = np.linspace(0.0, 1.0, 11)
    tilt, alb = {}, {}
    for k, c in enumerate(cases):
        ps = c.get("ps")
        if ps is None:
            continue
        col = f"C{k % 10}"
        lab = f"rho {c['rho']:g}, alpha {c['alpha']:g}"
        sel = ps["sel"]
        rr = (c["r"] / (math.sin(math.radians(c["alpha"]))))[sel]
        N = c["N"][sel]

        def polar(v):  # the angle from the axis: h = rho (N + beta a) lies in the plane of N and a
            return np.degrees(np.arctan2(np.hypot(v[:, 0], v[:, 1]), v[:, 2]))

        # signed tilt toward the axis, polar(N) - polar(h): unbiased by noise to first order (the
        # unsigned angle between noisy and true normals is not)
        t_rec = polar(N) - polar(ps["h_rec"][sel])
        t_cf = polar(N) - polar(ps["h_cf"][sel])
        a_rec = np.linalg.norm(ps["h_rec"][sel], axis=-1) / c["rho"]
        a_cf = np.linalg.norm(ps["h_cf"][sel], axis=-1) / c["rho"]
        b = np.clip(np.digitize(rr, bins) - 1, 0, len(bins) - 2)
        cnt = np.bincount(b, minlength=len(bins) - 1)
        ok = cnt > 0
        xm = (0.5 * (bins[1:] + bins[:-1]))[ok].tolist()

        def binned(v, _b=b, _cnt=cnt, _ok=ok):
            return (np.bincount(_b, v, minlength=len(bins) - 1)[_ok] / _cnt[_ok]).tolist()

        tilt[f"{lab}: recovered"] = {"x": xm, "y": binned(t_rec), "color": col}
        tilt[f"{lab}: closed form"] = {"x": xm, "y": binned(t_cf), "color": col, "linestyle": "--", "marker": ""}
        alb[f"{lab}: recovered"] = {"x": xm, "y": binned(a_rec), "color": col}
        alb[f"{lab}: closed form"] = {"x": xm, "y": binned(a_cf), "color": col, "linestyle": "--", "marker": ""}
    out = {}
    if tilt:
        out["radiosity_cap: photometric-stereo normal tilt vs closed form"] = {
            "x": None, "series": tilt, "xlabel": "distance from the axis / rim radius",
            "ylabel": "tilt toward the axis: polar angle of N - of recovered (deg)",
            "title": "concave cap: photometric stereo tilts normals toward the axis (beta)"}
        out["radiosity_cap: photometric-stereo albedo vs closed form"] = {
            "x": None, "series": alb, "xlabel": "distance from the axis / rim radius",
            "ylabel": "recovered albedo / true albedo", "title": "concave cap: recovered albedo |N + beta a| (inflated)"}
    return out
