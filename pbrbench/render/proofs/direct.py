"""The direct-light proofs: a Lambertian sphere, depth, an area source's shadow, the integrating
sphere and the direct/indirect decomposition, each against a closed form or an independent render
(the list is in :mod:`pbrbench.render.proofs`)."""

from __future__ import annotations

import math

import numpy as np

from pbrbench.quality import Quality, require
from pbrbench.render.proofs.common import Record, ground_truth_of, record
from pbrbench.scene.spec import SceneSpec
from pbrbench.shading import irradiance as irr

# --------------------------------------------------------------------------- scenes
SPHERE_ALBEDO = (0.2, 0.5, 0.8)
SPHERE_HW = 1.2
DIR_LIGHT = {"type": "directional", "direction": [1.0, 1.0, 2.0], "irradiance": 3.0}
POINT_LIGHT = {"type": "point", "position": [1.5, 2.0, 3.0], "intensity": 20.0}


def sphere_spec(light: dict, *, name: str, resolution: int = 64, spp: int = 8192) -> SceneSpec:
    """A Lambertian sphere (albedo (0.2, 0.5, 0.8)), orthographic, direct light only."""
    return SceneSpec.model_validate({
        "name": name, "description": "validation: Lambertian sphere under one delta source", "reference": "pbrbench validate, proof 1",
        "camera": {"type": "orthographic", "half_width": SPHERE_HW},
        "render": {"resolution": resolution, "spp": spp, "max_depth": 2, "sampler": "multijitter"},
        "materials": {"paint": {"type": "diffuse", "albedo": list(SPHERE_ALBEDO)}},
        "shapes": [{"name": "sphere", "type": "sphere", "radius": 1.0, "material": "paint"}],
        "lights": [light]})


def shadow_spec(*, occluded: bool = True, resolution: int = 64, spp: int = 16384) -> SceneSpec:
    """The geometry of the shipped library scene ``shadow_near`` (read from it when present), direct only."""
    from pbrbench.settings import LIBRARY_DIR

    base = None
    path = LIBRARY_DIR / "shadow_near.toml"
    if path.is_file():
        from pbrbench.scene.load import load_scene_file

        base = load_scene_file(path)[0]
    if base is not None:
        d = base.model_dump(mode="json", exclude={"base_dir", "source", "sweep"})
    else:  # the same geometry, stated here
        d = {"description": "area source, square occluder", "camera": {"type": "orthographic", "origin": [0, 0, 0.5], "half_width": 2.0},
             "materials": {"floor": {"type": "diffuse", "albedo": 0.5}, "black": {"type": "diffuse", "albedo": 0.0}},
             "shapes": [{"name": "floor", "type": "rectangle", "center": [0, 0, 0], "size": [8, 8], "material": "floor"},
                        {"name": "occluder", "type": "rectangle", "center": [0, 0, 1], "size": [0.5, 0.5], "material": "black", "occluder": True}],
             "lights": [{"type": "area", "center": [0, 0, 3], "size": [1, 1], "normal": [0, 0, -1], "radiance": 10.0}]}
    d["name"] = "validate_shadow"
    d["description"] = "validation: " + d["description"]
    d["render"] = {"resolution": resolution, "spp": spp, "max_depth": 2, "sampler": "multijitter"}
    if not occluded:
        d["shapes"] = [s for s in d["shapes"] if not s.get("occluder")]
    return SceneSpec.model_validate(d)


def integrating_sphere_spec(rho: float, *, resolution: int = 32, spp: int = 4096) -> SceneSpec:
    return SceneSpec.model_validate({
        "name": f"validate_integrating_sphere[albedo={rho:g}]", "description": "validation: closed Lambertian sphere, point source at the centre",
        "reference": "pbrbench validate, proof 3",
        "camera": {"type": "orthographic", "origin": [0.0, 0.0, 0.0], "target": [0.0, 0.0, -1.0], "half_width": 0.5},
        "render": {"resolution": resolution, "spp": spp, "max_depth": -1, "sampler": "multijitter"},
        "materials": {"wall": {"type": "diffuse", "albedo": rho}},
        "shapes": [{"name": "wall", "type": "sphere", "radius": 1.0, "flip_normals": True, "material": "wall"}],
        "lights": [{"type": "point", "position": [0.0, 0.0, 0.0], "intensity": 10.0}]})


PLANE_ROT = ({"axis": [1.0, 0.0, 0.0], "angle": 30.0}, {"axis": [0.0, 1.0, 0.0], "angle": 20.0})


def tilted_plane_spec(*, resolution: int = 64, spp: int = 1024) -> SceneSpec:
    return SceneSpec.model_validate({
        "name": "validate_tilted_plane", "description": "validation: tilted plane for the depth AOV", "reference": "pbrbench validate, proof 4",
        "camera": {"type": "orthographic", "origin": [0.0, 0.0, 5.0], "half_width": 1.0},
        "render": {"resolution": resolution, "spp": spp, "max_depth": 2},
        "shapes": [{"name": "plane", "type": "rectangle", "center": [0.0, 0.0, 0.0], "size": [6.0, 6.0], "rotate": list(PLANE_ROT)}],
        "lights": [{"type": "directional", "direction": [0.0, 0.0, 1.0], "irradiance": 1.0}]})


def gi_spec(*, seed: int = 0, resolution: int = 64, spp: int = 1024) -> SceneSpec:
    """A concave groove (albedo 0.7) lit by three distant sources one at a time: strong indirect light."""
    s2 = math.sqrt(2.0)
    return SceneSpec.model_validate({
        "name": f"validate_gi[seed={seed}]", "description": "validation: concave groove with interreflections", "reference": "pbrbench validate, proof 5",
        "camera": {"type": "orthographic", "origin": [0.0, 0.0, 3.0], "half_width": 1.0},
        "render": {"resolution": resolution, "spp": spp, "max_depth": -1, "seed": seed},
        "materials": {"paint": {"type": "diffuse", "albedo": 0.7}},
        "shapes": [{"name": "left", "type": "rectangle", "center": [-0.55, 0, 0.55], "size": [1.1 * s2, 4.0], "material": "paint",
                    "rotate": [{"axis": [0, 1, 0], "angle": 45.0}]},
                   {"name": "right", "type": "rectangle", "center": [0.55, 0, 0.55], "size": [1.1 * s2, 4.0], "material": "paint",
                    "rotate": [{"axis": [0, 1, 0], "angle": -45.0}]}],
        "light_set": [{"type": "directional", "direction": [-0.7071, 0.0, 0.7071], "irradiance": 3.0},
                      {"type": "directional", "direction": [0.0, 0.0, 1.0], "irradiance": 3.0},
                      {"type": "directional", "direction": [0.5, 0.3, 0.8], "irradiance": 3.0}]})


# --------------------------------------------------------------------------- helpers
def _pixel_size(spec: SceneSpec, quality: Quality) -> tuple[int, int, float]:
    w, h = require(quality).resolution(spec.render.resolution, spec.render.min_resolution)
    return w, h, 2.0 * spec.camera.half_width / w


def _interior(ref: irr.SphereReference, gt_mask: np.ndarray, *, lit_fraction: float = 0.05, min_nz: float = 0.3) -> np.ndarray:
    lum = ref.radiance
    return (gt_mask & (ref.coverage >= 1.0) & (lum >= lit_fraction * lum.max()) & (ref.centre_normals[..., 2] > min_nz))


# --------------------------------------------------------------------------- proof 1 + 4
def check_sphere(quality: Quality, cache, *, kind: str = "directional") -> list[Record]:
    """Proof 1 (and the normals of proof 4): sphere vs the box-filtered analytic image."""
    light = DIR_LIGHT if kind == "directional" else POINT_LIGHT
    spec = sphere_spec(light, name=f"validate_sphere_{kind}")
    gt = ground_truth_of(spec, quality, cache)
    w, h, _ = _pixel_size(spec, quality)
    kw = ({"direction": light["direction"], "irradiance": light["irradiance"]} if kind == "directional"
          else {"position": light["position"], "intensity": light["intensity"]})
    ref = irr.sphere_reference((w, h), SPHERE_HW, albedo=1.0, sub=32, **kw)
    refc = ref.radiance[..., None] * np.asarray(SPHERE_ALBEDO)
    img = gt["radiance"].astype(np.float64)
    inner = _interior(ref, gt.mask)
    rel = np.abs(img - refc)[inner] / refc[inner]
    bias = float(img[inner].mean() / refc[inner].mean() - 1)
    out = [record(f"sphere_{kind}", float(rel.max()), 1e-3,
                f"max relative error over {int(inner.sum())} interior pixels (covered, lit > 5 %, n_z > 0.3); "
                f"median {np.median(rel):.1e}, bias {bias:+.1e}; {w}x{h}, {gt.meta['spp']} spp")]
    edge = (ref.coverage > 0) & (ref.coverage < 1)
    edge_err = float(np.abs(img - refc)[edge].max() / refc.max()) if edge.any() else 0.0
    out.append(record(f"sphere_{kind}_silhouette", edge_err, 0.05,
                    f"max error of partly covered pixels / peak (exact coverage reference); {int(edge.sum())} pixels"))
    if kind == "directional":
        n = gt["normals"].astype(np.float64)
        m = gt.mask & (ref.coverage >= 1.0)
        cos = np.clip(np.sum(n * ref.normals, -1), -1, 1)
        ang = np.degrees(np.arccos(cos))[m]
        out.append(record("normals", float(ang.max()), 0.5,
                        f"max angle (deg) between AOV and box-averaged analytic normals over {int(m.sum())} covered pixels; "
                        f"mean {ang.mean():.2e}"))
    return out


def check_depth(quality: Quality, cache) -> list[Record]:
    """Proof 4: depth (along the view axis) and normals of a tilted plane vs the analytic plane."""
    spec = tilted_plane_spec()
    gt = ground_truth_of(spec, quality, cache)
    from pbrbench.shading.surfaces import pixel_grid

    w, h, px = _pixel_size(spec, quality)
    x, y = pixel_grid(h, w, spec.camera.half_width)
    # rotate +z by the spec's rotations (Mitsuba: each rotation applied in order, right-handed)
    n = np.array([0.0, 0.0, 1.0])
    for r in PLANE_ROT:
        n = _rotate(n, r["axis"], r["angle"])
    z = -(n[0] * x + n[1] * y) / n[2]
    depth_ref = spec.camera.origin[2] - z
    m = gt.mask
    err = np.abs(gt["depth"].astype(np.float64) - depth_ref)[m]
    slope = math.hypot(n[0] / n[2], n[1] / n[2])
    nerr = np.degrees(np.arccos(np.clip(gt["normals"].astype(np.float64)[m] @ n, -1, 1)))
    return [record("depth", float(err.max()), 0.01 * px * max(slope, 1.0),
                 f"max |depth - analytic| (world units) over {int(m.sum())} pixels; bound = 1 % of the depth change across a pixel "
                 f"({px * slope:.3g})"),
            record("normals_plane", float(nerr.max()), 0.5, "max angle (deg) between AOV normals and the plane normal")]


def _rotate(v, axis, angle_deg):
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    t = math.radians(angle_deg)
    return v * math.cos(t) + np.cross(a, v) * math.sin(t) + a * np.dot(a, v) * (1 - math.cos(t))


# --------------------------------------------------------------------------- proof 2
def check_area_source(quality: Quality, cache) -> list[Record]:
    """Proof 2: Lambert's formula without the occluder; penumbra profile and edges with it."""
    spec = shadow_spec()
    gt = ground_truth_of(spec, quality, cache)
    w, h, px = _pixel_size(spec, quality)
    light = spec.lights[0]
    src = irr.rectangle_polygon(light.center, light.size, light.normal, light.up)
    rad = float(np.mean(light.radiance))
    floor = next(s for s in spec.shapes if not s.occluder)
    occ_shape = next(s for s in spec.shapes if s.occluder)
    rho = float(np.mean(spec.material_of(floor).albedo))
    occ = irr.rectangle_polygon(occ_shape.center, occ_shape.size, (0, 0, 1))
    hw = spec.camera.half_width
    hh = hw * h / w
    sub = 4
    fx = -hw + (np.arange(w * sub) + 0.5) * px / sub
    fy = hh - (np.arange(h * sub) + 0.5) * px / sub
    X, Y = np.meshgrid(fx, fy)
    P = np.stack([X, Y, np.zeros_like(X)], -1)
    E = irr.polygon_irradiance(P, np.array([0.0, 0.0, 1.0]), src, rad)
    ref_un = (rho / np.pi) * E.reshape(h, sub, w, sub).mean(axis=(1, 3))
    un = gt["direct_unoccluded"].astype(np.float64).mean(-1)
    peak = ref_un.max()
    e1 = float(np.abs(un - ref_un).max() / peak)
    out = [record("area_source", e1, 0.01, f"max |render - Lambert's formula| / peak over all {w}x{h} pixels (no occluder); "
                                           f"peak radiance {peak:.4f}")]
    # penumbra profile: the two rows straddling y = 0, exact visible-part irradiance, 8x8 sub-samples
    rows = [h // 2 - 1, h // 2]
    sub = 8
    prof_ref = []
    for i in rows:
        y0 = hh - i * px
        ys = y0 - (np.arange(sub) + 0.5) * px / sub
        xs = -hw + (np.arange(w * sub) + 0.5) * px / sub
        XX, YY = np.meshgrid(xs, ys)
        pts = np.stack([XX, YY, np.zeros_like(XX)], -1).reshape(-1, 3)
        Ev = irr.visible_polygon_irradiance(pts, np.array([0.0, 0.0, 1.0]), src, [occ], rad)
        prof_ref.append((rho / np.pi) * Ev.reshape(sub, w, sub).mean(axis=(0, 2)))
    prof_ref = np.array(prof_ref)
    prof = gt["direct"].astype(np.float64).mean(-1)[rows]
    e2 = float(np.abs(prof - prof_ref).max() / peak)
    out.append(record("penumbra", e2, 0.02, f"max |render - exact visible-part irradiance| / peak along the rows through the shadow "
                                          f"({w} pixels x 2 rows)"))
    # umbra / penumbra edges along those rows, from the projection of the source through the occluder's edges
    regions = irr.shadow_regions(src[:, :2], light.center[2], occ[:, :2], occ_shape.center[2])
    frac = gt["unoccluded_fraction"].astype(np.float64)[rows].mean(0)
    xc = -hw + (np.arange(w) + 0.5) * px
    worst = 0.0
    detail = []
    umb = irr.interval_on_line(regions.umbra, 0.0) if len(regions.umbra) else None
    pen = irr.interval_on_line(regions.penumbra, 0.0)
    for name, interval, level in (("umbra", umb, 0.02), ("penumbra", pen, 0.98)):
        if interval is None:
            continue
        for side, x_pred in (("left", interval[0]), ("right", interval[1])):
            x_meas = _crossing(xc, frac, level, x_pred, outward=(side == "right"), inside_low=(name == "umbra"))
            d = abs(x_meas - x_pred) / px
            worst = max(worst, d)
            detail.append(f"{name} {side} {x_pred:+.3f}/{x_meas:+.3f}")
    out.append(record("shadow_edges", worst, 1.0, "max |measured - predicted| edge position in pixels (predicted/measured x: "
                                                 + ", ".join(detail) + ")"))
    return out


def _crossing(x: np.ndarray, f: np.ndarray, level: float, x_pred: float, *, outward: bool, inside_low: bool) -> float:
    """Where the profile ``f`` crosses ``level`` nearest to ``x_pred`` (linear interpolation)."""
    s = np.sign(f - level)
    idx = np.flatnonzero(s[:-1] * s[1:] < 0)
    if len(idx) == 0:
        return float("inf")
    xs = []
    for i in idx:
        t = (level - f[i]) / (f[i + 1] - f[i])
        xs.append(x[i] + t * (x[i + 1] - x[i]))
    xs = np.array(xs)
    return float(xs[np.argmin(np.abs(xs - x_pred))])


# --------------------------------------------------------------------------- proof 3
def check_integrating_sphere(quality: Quality, cache, albedos=(0.3, 0.6, 0.9)) -> list[Record]:
    """Proof 3: inside a closed sphere, radiance = direct / (1 - rho)."""
    out = []
    for rho in albedos:
        spec = integrating_sphere_spec(rho)
        gt = ground_truth_of(spec, quality, cache)
        d_ref, g_ref = irr.integrating_sphere_radiance(rho, 10.0, 1.0)
        g = float(gt["radiance"].astype(np.float64).mean())
        d = float(gt["direct"].astype(np.float64).mean())
        sd = float(np.sqrt(np.mean(gt["radiance_sd"].astype(np.float64) ** 2) / gt["radiance"].size))
        out.append(record(f"integrating_sphere[rho={rho:g}]", abs(g / g_ref - 1), 0.01,
                        f"image mean {g:.5f} vs L_d/(1-rho) = {g_ref:.5f} (sd of the mean ~{sd / g_ref:.1e} relative); "
                        f"direct {d:.6f} vs {d_ref:.6f} ({abs(d / d_ref - 1):.1e})"))
    return out


# --------------------------------------------------------------------------- proof 5
def check_decomposition(quality: Quality, cache, *, alpha: float = 0.01, diagnostics_dir=None) -> list[Record]:
    """Proof 5: direct + indirect (seed 0) vs global (seed 1); sum of per-light images vs all lights."""
    from pbrbench.render.stats import compare_images

    a = ground_truth_of(gi_spec(seed=0), quality, cache)
    # b: the same lights as the scene's own lights, not a light set, so that its radiance and direct
    # passes are renders with every light in the scene (a's are the sums of its per-light passes)
    g1 = gi_spec(seed=1)
    b = ground_truth_of(g1.model_copy(update={"name": "validate_gi_all_lights[seed=1]", "lights": g1.light_set,
                                              "light_set": ()}), quality, cache)
    img = a["direct"].astype(np.float64) + a["indirect"].astype(np.float64)
    # indirect = radiance - direct with shared seeds, so the noise of direct + indirect is that of radiance
    r1 = compare_images(img, b["radiance"], b["radiance_sd"], image_sd=a["radiance_sd"], alpha=alpha,
                        diagnostics_dir=diagnostics_dir, name="decomposition")
    out = [record("decomposition", r1.n_rejected, 0, "direct + indirect (seed 0) vs global radiance (seed 1): "
                + r1.summary(), passed=r1.passed)]
    # a's radiance is the sum of its per-light renders (seed 0; its sd is the sum's), b's an
    # all-lights render (seed 1): independent estimates of one image
    lights = a.light_stack("radiance").astype(np.float64).sum(0)
    r2 = compare_images(lights, b["radiance"], b["radiance_sd"], image_sd=a["radiance_sd"], alpha=alpha,
                        diagnostics_dir=diagnostics_dir, name="light_sum")
    out.append(record("light_sum", r2.n_rejected, 0, f"sum of {a.n_lights} per-light renders (seed 0) vs an "
                      "all-lights render (seed 1): " + r2.summary(), passed=r2.passed))
    dsum = a.light_stack("direct").astype(np.float64).sum(0)
    r3 = compare_images(dsum, b["direct"], b["direct_sd"], image_sd=a["direct_sd"], alpha=alpha,
                        diagnostics_dir=diagnostics_dir, name="light_sum_direct")
    out.append(record("light_sum_direct", r3.n_rejected, 0, "sum of per-light direct renders (seed 0) vs an "
                      "all-lights direct render (seed 1): " + r3.summary(), passed=r3.passed))
    return out
