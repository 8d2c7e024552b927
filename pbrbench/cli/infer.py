"""``pbrbench infer``: run the inference package on your own data.

* ``photometric-stereo DIR --out OUT``: DIR is a DiLiGenT- or psmImages-layout object folder or a folder
  written by ``pbrbench render --out``; writes normals (EXR + PNG), albedo, the height by
  integration, the valid mask and ``result.json`` (with the angular error when DIR has
  ground-truth normals);
* ``retinex IMAGE --out OUT``: IMAGE is an image file (EXR, 16-bit PNG, TIFF, JPEG, ...) or an
  MIT-Intrinsic-layout object folder (its grey image, or with ``--colour`` its colour one, for
  ``--method grosse2009`` and its ``--chromaticity-threshold``); writes reflectance and shading
  (EXR + PNG);
* ``hdr DIR --out OUT``: DIR is an exposure bracket (images plus a times file, or EXIF times);
  writes the merged radiance (EXR + tone-mapped PNG) and the inverse response (CSV).

A malformed input (a missing, empty or damaged file, non-numeric text, NaN values, mismatched
sizes, a saturated or empty stack, exposure times out of order with the brightness) is one
line naming the file and the fix, exit code 1.  Data that loads but may be wrong is a
``pbrbench: warning: ...`` line, also listed under ``warnings`` in ``result.json``.
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
import warnings
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
                 help="normals, albedo and height from a DiLiGenT- or psmImages-layout folder or a pbrbench render",
                 fill=_add_ps_options)
    s.add_parser("retinex", aliases=["lightness"], help="reflectance and shading from one image",
                 fill=_add_retinex_options)
    s.add_parser("hdr", help="camera response and merged radiance from an exposure bracket", fill=_add_hdr_options)


def default_method(dispatcher, param: str = "method") -> str:
    """The default of a dispatcher's ``method`` argument: the command line offers the same default
    as the Python call (one place decides it)."""
    import inspect

    return inspect.signature(dispatcher).parameters[param].default


def _add_ps_options(ps):
    from pbrbench.infer.integration import METHODS as INTEGRATION
    from pbrbench.infer.integration import integrate_normals
    from pbrbench.infer.photometric_stereo import METHODS as PS
    from pbrbench.infer.photometric_stereo import solve_photometric_stereo

    ps.add_argument("dir", metavar="DIR")
    ps.add_argument("--out", required=True, metavar="OUT")
    d_ps, d_int = default_method(solve_photometric_stereo), default_method(integrate_normals)
    ps.add_argument("--method", choices=list(PS), default=d_ps, help=f"default: {d_ps}")
    ps.add_argument("--integrate", choices=list(INTEGRATION), default=d_int,
                    help=f"surface integration of the normals (default: {d_int})")
    ps.add_argument("--drop-first", type=int, default=0, metavar="N",
                    help="leave out the first N images (e.g. 20 for DiLiGenT's bearPNG)")
    ps.set_defaults(func=run_ps)


def _add_retinex_options(rx):
    from pbrbench.infer.lightness import METHODS as LIGHTNESS
    from pbrbench.infer.lightness import estimate_lightness

    rx.add_argument("image", metavar="IMAGE", help="an image file, or an MIT Intrinsic Images object folder")
    rx.add_argument("--out", required=True, metavar="OUT")
    d_rx = default_method(estimate_lightness)
    rx.add_argument("--method", choices=list(LIGHTNESS), default=d_rx, help=f"default: {d_rx}")
    rx.add_argument("--threshold", type=float, default=None, help="log-gradient threshold (the method's default)")
    rx.add_argument("--chromaticity-threshold", type=float, default=None, metavar="T",
                    help="grosse2009 (colour retinex): a gradient is paint also where its chromaticity log-gradient "
                         "exceeds T (the method's default; inf: luminance only)")
    rx.add_argument("--colour", action="store_true",
                    help="with an MIT Intrinsic Images folder: decompose the colour diffuse image (H, W, 3) instead "
                         "of its grey channel mean (the colour protocol; grosse2009 uses the chromaticity)")
    rx.add_argument("--mask", default=None, metavar="FILE", help="a mask image (non-zero = use)")
    rx.add_argument("--gamma", choices=["auto", "linear", "srgb"], default="auto",
                    help="pixel encoding: auto = 8-bit files are sRGB, 16-bit / float are linear")
    rx.set_defaults(func=run_retinex)


def _add_hdr_options(hd):
    from pbrbench.infer.hdr import CALIBRATION_METHODS, MERGE_METHODS, calibrate_response, merge_hdr

    hd.add_argument("dir", metavar="DIR")
    hd.add_argument("--out", required=True, metavar="OUT")
    d_cal, d_merge = default_method(calibrate_response), default_method(merge_hdr)
    hd.add_argument("--method", choices=list(CALIBRATION_METHODS), default=d_cal, help=f"default: {d_cal}")
    hd.add_argument("--merge", choices=list(MERGE_METHODS), default=d_merge, help=f"default: {d_merge}")
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


@contextlib.contextmanager
def _data_warnings(seen: list):
    """Print each data warning of the loaders as one ``pbrbench: warning:`` line; collect them."""
    from pbrbench.datasets.files import DataWarning

    def show(message, category, *_args, **_kw):
        if issubclass(category, DataWarning):
            text = " ".join(str(message).split())
            if text not in seen:
                seen.append(text)
                _log(f"warning: {text}")
        else:
            old(message, category, *_args, **_kw)

    old = warnings.showwarning
    with warnings.catch_warnings():
        warnings.simplefilter("always", DataWarning)
        warnings.showwarning = show
        try:
            yield seen
        finally:
            warnings.showwarning = old


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

    from pbrbench.datasets import is_diligent, is_psm, load_diligent, load_psm

    if not d.is_dir():
        raise UserError(f"{d}: no such folder")
    if is_diligent(d):
        obj = load_diligent(d, indices=None, log=_log)
        sel = slice(drop, None)
        return obj.name, obj.grey[sel], obj.lights[sel], obj.mask, obj.normals, 1.0, "DiLiGenT layout"
    if is_psm(d):
        obj = load_psm(d, log=_log)
        sel = slice(drop, None)
        return obj.name, obj.grey[sel], obj.lights[sel], obj.mask, None, 1.0, "psmImages layout"
    if (d / "gt.json").is_file() and (d / "gt.exr").is_file():
        return _ps_render(d, drop)
    raise UserError(f"{d}: neither a DiLiGenT object folder (light_directions.txt, 001.png ..., mask.png), a "
                    "psmImages object folder (lights.txt, name.0.tga ..., name.mask.tga) nor a "
                    "`pbrbench render --out` folder (gt.exr, gt.json)")


def _ps_render(d: Path, drop: int):
    """The inputs of a ``pbrbench render --out`` folder, every fault a line naming the file."""
    import numpy as np

    from pbrbench import io
    from pbrbench.datasets.files import quiet_stderr

    js, exr = d / "gt.json", d / "gt.exr"
    again = "render it again with `pbrbench render SCENE --out DIR`"
    try:
        meta = json.loads(js.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as e:
        raise UserError(f"{js}: not valid JSON ({' '.join(str(e).split())[:120]}); {again}") from None
    if not isinstance(meta, dict):
        raise UserError(f"{js}: a JSON {type(meta).__name__}, not an object; {again}")
    try:
        if exr.stat().st_size == 0:
            raise UserError(f"{exr}: an empty file (0 bytes); {again}")
        with quiet_stderr():
            r = io.load_render(d)
    except UserError:
        raise
    except MemoryError:
        raise UserError(f"{exr}: too large to load; {again} at a lower resolution") from None
    except Exception as e:  # noqa: BLE001 - the EXR decoder raises anything on a damaged file
        raise UserError(f"{exr}: not a readable render ({' '.join(str(e).split())[:120]}); {again}") from None
    try:
        lv = meta.get("light_vectors")
        if lv is None:
            raise UserError(f"{js}: the scene has no light set (no per-light images); render a scene with a light set")
        lights = np.asarray(lv, dtype=np.float64)
        k = len(r.lights) or sum(1 for n in r.keys() if n.startswith("light") and n.endswith(".radiance"))
        if lights.ndim != 2 or lights.shape[1] != 3 or not np.isfinite(lights).all():
            raise UserError(f"{js}: light_vectors must be a list of finite (x, y, z) vectors, got shape {lights.shape}; "
                            f"{again}")
        if not (np.linalg.norm(lights, axis=1) > 0).all():
            raise UserError(f"{js}: a zero vector in light_vectors; {again}")
        if len(lights) != k:
            raise UserError(f"{js}: {len(lights)} light_vectors for {k} per-light images in {exr.name}; {again}")
        imgs = r.light_stack("radiance").astype(np.float64)
        normals = np.asarray(r["normals"], np.float64)
        mask = r.mask
        px = float(r.camera.get("pixel_size", 1.0))
    except UserError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as e:
        raise UserError(f"{d}: gt.json and gt.exr do not match ({' '.join(str(e).split())[:120]}); {again}") from None
    if imgs.ndim != 4 or imgs.shape[1:3] != mask.shape or normals.shape != mask.shape + (3,):
        raise UserError(f"{exr}: per-light images {imgs.shape}, mask {mask.shape}, normals {normals.shape} disagree; "
                        f"{again}")
    if not (np.isfinite(px) and px > 0):
        raise UserError(f"{js}: camera.pixel_size {px!r} must be a positive number; {again}")
    if not np.isfinite(imgs[:, mask]).all():
        raise UserError(f"{exr}: NaN or infinite radiance inside the mask; {again}")
    if not mask.any():
        raise UserError(f"{exr}: the mask is empty (no pure pixel); {again} with the object in view")
    return (str(meta.get("scene", d.name)), imgs.mean(axis=-1)[drop:], lights[drop:], mask,
            np.where(np.isfinite(normals), normals, 0.0), px, "pbrbench render")


def run_ps(args) -> int:
    import numpy as np

    from pbrbench import io
    from pbrbench.infer.integration import integrate_normals
    from pbrbench.infer.photometric_stereo import solve_photometric_stereo
    from pbrbench.metrics.normals import angular_error_stats, largest_component

    if args.drop_first < 0:
        raise UserError(f"--drop-first {args.drop_first}: give N >= 0")
    st = _Stages("photometric stereo", ["load", f"normals ({args.method})", f"height ({args.integrate})", "write"])
    with _data_warnings([]) as seen:
        name, imgs, lights, mask, n_true, px, layout = _ps_input(Path(args.dir), args.drop_first)
    if len(imgs) < 3:
        raise UserError(f"{args.dir}: {len(imgs)} image(s) after --drop-first; photometric stereo needs 3 or more")
    st.next(f"{len(imgs)} images {imgs.shape[1]}x{imgs.shape[2]} ({layout})")
    t0 = time.perf_counter()
    try:
        res = solve_photometric_stereo(imgs, lights, method=args.method, mask=mask)
    except ValueError as e:
        raise UserError(f"{args.dir}: photometric stereo ({args.method}): {e}") from None
    t_ps = time.perf_counter() - t0
    st.next()
    dom = largest_component(res.valid & (res.normals[..., 2] > 1e-3))
    try:
        z = integrate_normals(res.normals, mask=dom, method=args.integrate, pixel_size=px)
    except ValueError as e:
        raise UserError(f"{args.dir}: integration ({args.integrate}): {e}") from None
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
               "frame": "x right, y up, z toward the camera", "warnings": seen,
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


def _rx_input(path: Path, gamma: str, mask_file, colour: bool = False):
    import numpy as np

    from pbrbench.datasets import is_mit, load_mit_object
    from pbrbench.datasets.files import load_image, read_mask

    if path.is_dir():
        if not is_mit(path):
            raise UserError(f"{path}: a folder, but not an MIT Intrinsic Images object (diffuse.png, reflectance.png)")
        obj = load_mit_object(path)
        try:
            mask = read_mask(Path(mask_file), obj.mask.shape) if mask_file else obj.mask
        except ValueError as e:
            raise UserError(f"--mask {e}") from None
        if colour:
            return obj.name, obj.diffuse, mask, "MIT layout (colour diffuse image, linear)"
        return obj.name, obj.image, mask, "MIT layout (grey diffuse image, linear)"
    if colour:
        raise UserError(f"--colour chooses the colour image of an MIT Intrinsic Images folder; {path} is a file, "
                        "whose channels are used as they are: drop --colour")
    a = load_image(path, "image")
    if a.ndim == 3 and a.shape[2] in (1, 2, 4):
        a = a[..., :-1] if a.shape[2] == 4 else a[..., 0]
    if a.ndim == 3 and a.shape[2] != 3:
        raise UserError(f"{path}: {a.shape[2]} channels; give a grey or RGB image")
    if a.dtype.kind == "f":
        img, enc = a.astype(float), "float, linear"
    elif a.dtype.kind == "b":
        raise UserError(f"{path}: a boolean array; give the image's intensities")
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
        raise UserError(f"--mask {e}") from None
    return path.stem, img, mask, enc


def run_retinex(args) -> int:
    import numpy as np

    from pbrbench import io
    from pbrbench.infer.lightness import estimate_lightness

    st = _Stages("retinex", ["load", f"decompose ({args.method})", "write"])
    with _data_warnings([]) as seen:
        name, img, mask, enc = _rx_input(Path(args.image), args.gamma, args.mask, colour=args.colour)
    st.next(f"{img.shape[1]}x{img.shape[0]} ({enc})")
    opts = {"threshold": args.threshold} if args.threshold is not None else {}
    if args.chromaticity_threshold is not None:   # checked by the method (>= 0 or inf), its message one line
        opts["chromaticity_threshold"] = args.chromaticity_threshold
    valid = (img > 0) if img.ndim == 2 else (img > 0).all(axis=-1)
    m = valid if mask is None else (mask & valid)
    if not m.any():
        raise UserError(f"{args.image}: no pixel > 0 (inside the mask); retinex works on log intensities")
    t0 = time.perf_counter()
    try:
        refl, shad = estimate_lightness(np.where((m[..., None] if img.ndim == 3 else m), img, 0.0),
                                        method=args.method, mask=m, **opts)
    except ValueError as e:
        raise UserError(f"{args.image}: retinex ({args.method}): {e}") from None
    st.next()
    out = _out(args.out)
    io.write_exr_image(out / "reflectance.exr", refl)
    io.write_exr_image(out / "shading.exr", shad)
    io.write_preview(out / "reflectance.png", refl, percentile=100.0)
    io.write_preview(out / "shading.png", shad)
    (out / "result.json").write_text(json.dumps({"input": str(Path(args.image).resolve()), "encoding": enc,
                                                 "method": args.method, "options": opts, "warnings": seen,
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
    if not Path(args.dir).is_dir():
        raise UserError(f"{args.dir}: no such folder; give the folder of the bracket's images")
    with _data_warnings([]) as seen:
        b = load_bracket(Path(args.dir))
    st.next(f"{len(b.files)} exposures {b.exposure_times.min():g}-{b.exposure_times.max():g} s ({b.source})")
    try:
        resp = calibrate_response(b.images, b.exposure_times, method=args.method)
        st.next()
        times = resp.exposure_times if resp.exposure_times is not None else b.exposure_times
        rad = merge_hdr(b.images, times, resp, method=args.merge)
    except ValueError as e:
        raise UserError(f"{args.dir}: hdr ({args.method}): {e}") from None
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
        "exposure_times": b.exposure_times.tolist(), "times_from": b.source, "notes": b.notes, "warnings": seen,
        "method": args.method, "merge": args.merge,
        "response": "response.csv: f^-1(level) per channel, relative exposure, f^-1(top level) = 1",
        "radiance_units": "relative linear radiance (exposure / second, up to one global scale)"}, indent=1))
    st.next()
    lo, hi = np.percentile(rad[rad > 0], [1, 99]) if np.any(rad > 0) else (0, 0)
    print(f"{Path(args.dir).name}: {len(b.files)} exposures, {args.method} + {args.merge}; radiance 1-99 % range "
          f"{hi / max(lo, 1e-30):.3g}:1; wrote {out.resolve()}/radiance.(exr, png), response.csv")
    return 0
