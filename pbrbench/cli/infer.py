"""``pbrbench infer``: run the inference package on your own data.

* ``photometric-stereo DIR --out OUT``: DIR is a DiLiGenT-layout object folder or a folder
  written by ``pbrbench render --out``; writes normals (EXR + PNG), albedo, the height by
  integration, the valid mask and ``result.json`` (with the angular error when DIR has
  ground-truth normals);
* ``retinex IMAGE --out OUT``: IMAGE is an image file (EXR, 16-bit PNG, TIFF, JPEG, ...) or an
  MIT-Intrinsic-layout object folder; writes reflectance and shading (EXR + PNG);
* ``hdr DIR --out OUT``: DIR is an exposure bracket (images plus a times file, or EXIF times);
  writes the merged radiance (EXR + tone-mapped PNG) and the inverse response (CSV).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from pbrbench.errors import UserError


def register(sub):
    # the methods tables (and with them the inference package, SciPy) are imported only when
    # `pbrbench infer PROBLEM` is parsed or its help shown (main.Parser's fill)
    sub.add_parser("infer", help="run inference on your own data (DiLiGenT folder, image, bracket)",
                   description=__doc__.split("\n", 2)[2].strip(), formatter_class=_raw(), fill=_add_problems)


def _add_problems(p):
    s = p.add_subparsers(dest="problem", metavar="PROBLEM")
    s.required = True
    s.add_parser("photometric-stereo", aliases=["photometric_stereo"],
                 help="normals, albedo and height from a DiLiGenT-layout folder or a pbrbench render",
                 fill=_add_ps_options)
    s.add_parser("retinex", aliases=["lightness"], help="reflectance and shading from one image",
                 fill=_add_retinex_options)
    s.add_parser("hdr", help="camera response and merged radiance from an exposure bracket", fill=_add_hdr_options)


def _add_ps_options(ps):
    from pbrbench.infer.integration import METHODS as INTEGRATION
    from pbrbench.infer.photometric_stereo import METHODS as PS

    ps.add_argument("dir", metavar="DIR")
    ps.add_argument("--out", required=True, metavar="OUT")
    ps.add_argument("--method", choices=list(PS), default="woodham1980", help="default: woodham1980")
    ps.add_argument("--integrate", choices=list(INTEGRATION), default="lsq",
                    help="surface integration of the normals (default: lsq)")
    ps.add_argument("--drop-first", type=int, default=0, metavar="N",
                    help="leave out the first N images (e.g. 20 for DiLiGenT's bearPNG)")
    ps.set_defaults(func=run_ps)


def _add_retinex_options(rx):
    from pbrbench.infer.lightness import METHODS as LIGHTNESS

    rx.add_argument("image", metavar="IMAGE", help="an image file, or an MIT Intrinsic Images object folder")
    rx.add_argument("--out", required=True, metavar="OUT")
    rx.add_argument("--method", choices=list(LIGHTNESS), default="blake1985", help="default: blake1985")
    rx.add_argument("--threshold", type=float, default=None, help="log-gradient threshold (the method's default)")
    rx.add_argument("--mask", default=None, metavar="FILE", help="a mask image (non-zero = use)")
    rx.add_argument("--gamma", choices=["auto", "linear", "srgb"], default="auto",
                    help="pixel encoding: auto = 8-bit files are sRGB, 16-bit / float are linear")
    rx.set_defaults(func=run_retinex)


def _add_hdr_options(hd):
    from pbrbench.infer.hdr import CALIBRATION_METHODS, MERGE_METHODS
    from pbrbench.infer.hdr.merge import DEFAULT_MERGE

    hd.add_argument("dir", metavar="DIR")
    hd.add_argument("--out", required=True, metavar="OUT")
    hd.add_argument("--method", choices=list(CALIBRATION_METHODS), default="debevec1997", help="default: debevec1997")
    hd.add_argument("--merge", choices=list(MERGE_METHODS), default=DEFAULT_MERGE,
                    help=f"default: {DEFAULT_MERGE} (merge_hdr's)")
    hd.set_defaults(func=run_hdr)


def _raw():
    import argparse

    return argparse.RawDescriptionHelpFormatter


def _log(msg):
    print(f"pbrbench: {msg}", file=sys.stderr, flush=True)


def _out(path) -> Path:
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


class _Stages:
    """One progress line per stage (``pbrbench: photometric stereo 2/3: normals``)."""

    def __init__(self, what, names):
        self.what, self.names, self.i, self.t0 = what, names, 0, time.perf_counter()

    def next(self, note=""):
        self.i += 1
        _log(f"{self.what} {self.i}/{len(self.names)}: {self.names[self.i - 1]}{' ' + note if note else ''} "
             f"({time.perf_counter() - self.t0:.1f} s)")


# ----------------------------------------------------------------------------- photometric stereo
def _ps_input(d: Path, drop: int):
    """(name, grey images (K, H, W), lights (K, 3), mask, true normals or None, pixel size)."""
    import numpy as np

    from pbrbench.datasets import is_diligent, load_diligent

    if not d.is_dir():
        raise UserError(f"{d}: no such folder")
    if is_diligent(d):
        obj = load_diligent(d, indices=None, log=_log)
        sel = slice(drop, None)
        return obj.name, obj.grey[sel], obj.lights[sel], obj.mask, obj.normals, 1.0, "DiLiGenT layout"
    if (d / "gt.json").is_file() and (d / "gt.exr").is_file():
        from pbrbench import io

        r = io.load_render(d)
        if r.light_vectors is None:
            raise UserError(f"{d}/gt.json: the scene has no light set (no per-light images)")
        imgs = r.light_stack("radiance").astype(np.float64).mean(axis=-1)[drop:]   # grey, as the benchmark
        return (r.meta.get("scene", d.name), imgs, r.light_vectors[drop:], r.mask,
                r["normals"].astype(float), float(r.camera.get("pixel_size", 1.0)), "pbrbench render")
    raise UserError(f"{d}: neither a DiLiGenT object folder (light_directions.txt, 001.png ..., mask.png) nor a "
                    "`pbrbench render --out` folder (gt.exr, gt.json)")


def run_ps(args) -> int:
    import numpy as np

    from pbrbench import io
    from pbrbench.infer.integration import integrate_normals
    from pbrbench.infer.photometric_stereo import photometric_stereo
    from pbrbench.metrics.normals import angular_error_stats, largest_component

    if args.drop_first < 0:
        raise UserError(f"--drop-first {args.drop_first}: give N >= 0")
    st = _Stages("photometric stereo", ["load", f"normals ({args.method})", f"height ({args.integrate})", "write"])
    name, imgs, lights, mask, n_true, px, layout = _ps_input(Path(args.dir), args.drop_first)
    if len(imgs) < 3:
        raise UserError(f"{args.dir}: {len(imgs)} image(s) after --drop-first; photometric stereo needs 3 or more")
    st.next(f"{len(imgs)} images {imgs.shape[1]}x{imgs.shape[2]} ({layout})")
    t0 = time.perf_counter()
    try:
        res = photometric_stereo(imgs, lights, method=args.method, mask=mask)
    except ValueError as e:
        raise UserError(f"photometric stereo ({args.method}): {e}") from None
    t_ps = time.perf_counter() - t0
    st.next()
    dom = largest_component(res.valid & (res.normals[..., 2] > 1e-3))
    try:
        z = integrate_normals(res.normals, mask=dom, method=args.integrate, pixel_size=px)
    except ValueError as e:
        raise UserError(f"integration ({args.integrate}): {e}") from None
    z = np.where(dom, z - (z[dom].mean() if dom.any() else 0.0), 0.0)
    st.next()
    out = _out(args.out)
    io.write_exr_image(out / "normals.exr", res.normals)
    io.write_normals_png(out / "normals.png", res.normals, res.valid)
    alb = np.asarray(res.albedo, float)
    io.write_exr_image(out / "albedo.exr", alb)
    io.write_preview(out / "albedo.png", np.where(res.valid[..., None] if alb.ndim == 3 else res.valid, alb, 0.0))
    io.write_exr_image(out / "height.exr", z)
    io.write_colormap_png(out / "height.png", z, label="height (offset removed)", mask=dom)
    io.write_mask_png(out / "valid.png", res.valid)
    summary = {"input": str(Path(args.dir).resolve()), "layout": layout, "object": name, "method": args.method,
               "integration": args.integrate, "images": int(len(imgs)), "shape": list(imgs.shape[1:3]),
               "pixel_size": px, "seconds": t_ps, "valid_fraction": float(res.valid[mask].mean()) if mask.any() else 0.0,
               "frame": "x right, y up, z toward the camera",
               "files": ["normals.exr", "normals.png", "albedo.exr", "albedo.png", "height.exr", "height.png", "valid.png"]}
    if n_true is not None:
        sel = mask & (np.linalg.norm(n_true, axis=-1) > 0)
        if sel.any():
            e = angular_error_stats(np.where(res.valid[..., None], res.normals, 0.0), n_true, sel)
            summary["angular_error_deg"] = {"mean": e["mean"], "median": e["median"], "pixels": e["n_pixels"]}
    (out / "result.json").write_text(json.dumps(summary, indent=1))
    st.next()
    line = f"{name}: {args.method} on {len(imgs)} images, {summary['valid_fraction']:.0%} of the mask valid"
    if "angular_error_deg" in summary:
        a = summary["angular_error_deg"]
        line += f"; angular error mean {a['mean']:.2f} deg, median {a['median']:.2f} deg"
    print(line)
    print(f"wrote {out.resolve()}/(normals, albedo, height).(exr, png), valid.png, result.json")
    return 0


# ----------------------------------------------------------------------------- retinex
def _srgb_decode(x):
    import numpy as np

    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _rx_input(path: Path, gamma: str, mask_file):
    import numpy as np

    from pbrbench import io
    from pbrbench.datasets import is_mit, load_mit_object
    from pbrbench.datasets.files import read_mask

    if path.is_dir():
        if not is_mit(path):
            raise UserError(f"{path}: a folder, but not an MIT Intrinsic Images object (diffuse.png, reflectance.png)")
        obj = load_mit_object(path)
        mask = read_mask(Path(mask_file), obj.mask.shape) if mask_file else obj.mask
        return obj.name, obj.image, mask, "MIT layout (grey diffuse image, linear)"
    try:
        a = np.asarray(io.read_image(path))
    except ValueError as e:
        raise UserError(str(e)) from None
    if a.ndim == 3 and a.shape[2] in (2, 4):
        a = a[..., :-1] if a.shape[2] == 4 else a[..., 0]
    if a.ndim not in (2, 3):
        raise UserError(f"{path}: shape {a.shape}; give one (H, W) or (H, W, 3) image")
    if a.dtype.kind == "f":
        img, enc = a.astype(float), "float, linear"
    elif a.dtype.kind in "ui":
        top = 65535.0 if a.dtype.itemsize > 1 else 255.0
        img = a.astype(float) / top
        srgb = gamma == "srgb" or (gamma == "auto" and a.dtype.itemsize == 1)
        img, enc = (_srgb_decode(img), f"{8 * a.dtype.itemsize}-bit, sRGB decoded") if srgb else \
            (img, f"{8 * a.dtype.itemsize}-bit, linear")
    else:
        raise UserError(f"{path}: pixel type {a.dtype}")
    if gamma == "srgb" and a.dtype.kind == "f":
        img, enc = _srgb_decode(np.clip(img, 0, 1)), "float, sRGB decoded"
    try:
        mask = read_mask(Path(mask_file), img.shape[:2]) if mask_file else None
    except ValueError as e:
        raise UserError(str(e)) from None
    return path.stem, img, mask, enc


def run_retinex(args) -> int:
    import numpy as np

    from pbrbench import io
    from pbrbench.infer.lightness import lightness

    st = _Stages("retinex", ["load", f"decompose ({args.method})", "write"])
    name, img, mask, enc = _rx_input(Path(args.image), args.gamma, args.mask)
    st.next(f"{img.shape[1]}x{img.shape[0]} ({enc})")
    opts = {"threshold": args.threshold} if args.threshold is not None else {}
    valid = (img > 0) if img.ndim == 2 else (img > 0).all(axis=-1)
    m = valid if mask is None else (mask & valid)
    if not m.any():
        raise UserError(f"{args.image}: no pixel > 0 (inside the mask); retinex works on log intensities")
    t0 = time.perf_counter()
    try:
        refl, shad = lightness(np.where((m[..., None] if img.ndim == 3 else m), img, 0.0), method=args.method,
                               mask=m, **opts)
    except ValueError as e:
        raise UserError(f"retinex ({args.method}): {e}") from None
    st.next()
    out = _out(args.out)
    io.write_exr_image(out / "reflectance.exr", refl)
    io.write_exr_image(out / "shading.exr", shad)
    io.write_preview(out / "reflectance.png", refl, percentile=100.0)
    io.write_preview(out / "shading.png", shad)
    (out / "result.json").write_text(json.dumps({"input": str(Path(args.image).resolve()), "encoding": enc,
                                                 "method": args.method, "options": opts,
                                                 "seconds": time.perf_counter() - t0,
                                                 "files": ["reflectance.exr", "reflectance.png", "shading.exr",
                                                           "shading.png"]}, indent=1))
    st.next()
    print(f"{name}: {args.method} on {img.shape[1]}x{img.shape[0]} ({enc}); wrote {out.resolve()}/(reflectance, shading).(exr, png)")
    return 0


# ----------------------------------------------------------------------------- hdr
def run_hdr(args) -> int:
    import numpy as np

    from pbrbench import io
    from pbrbench.datasets import load_bracket
    from pbrbench.infer.hdr import calibrate_response, merge_hdr

    st = _Stages("hdr", ["load", f"calibrate ({args.method})", f"merge ({args.merge})", "write"])
    b = load_bracket(Path(args.dir))
    st.next(f"{len(b.files)} exposures {b.exposure_times.min():g}-{b.exposure_times.max():g} s ({b.source})")
    try:
        resp = calibrate_response(b.images, b.exposure_times, method=args.method)
        st.next()
        times = resp.exposure_times if resp.exposure_times is not None else b.exposure_times
        rad = merge_hdr(b.images, times, resp, method=args.merge)
    except ValueError as e:
        raise UserError(f"hdr ({args.method}): {e}") from None
    st.next()
    out = _out(args.out)
    io.write_exr_image(out / "radiance.exr", rad)
    io.write_preview(out / "radiance.png", rad)
    inv = resp.inverse
    header = "level," + ",".join(f"inverse_c{c}" for c in range(inv.shape[1]))
    rows = "\n".join(f"{z}," + ",".join(repr(float(v)) for v in inv[z]) for z in range(inv.shape[0]))
    (out / "response.csv").write_text(header + "\n" + rows + "\n")
    (out / "result.json").write_text(json.dumps({
        "input": str(Path(args.dir).resolve()), "files": [str(f.name) for f in b.files],
        "exposure_times": b.exposure_times.tolist(), "times_from": b.source, "notes": b.notes,
        "method": args.method, "merge": args.merge,
        "response": "response.csv: f^-1(level) per channel, relative exposure, f^-1(top level) = 1",
        "radiance_units": "relative linear radiance (exposure / second, up to one global scale)"}, indent=1))
    st.next()
    lo, hi = np.percentile(rad[rad > 0], [1, 99]) if np.any(rad > 0) else (0, 0)
    print(f"{Path(args.dir).name}: {len(b.files)} exposures, {args.method} + {args.merge}; radiance 1-99 % range "
          f"{hi / max(lo, 1e-30):.3g}:1; wrote {out.resolve()}/radiance.(exr, png), response.csv")
    return 0
