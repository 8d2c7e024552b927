"""``pbrbench render SCENE...``: render ground truth (cached) and write EXRs and PNG previews."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from pbrbench.cli.common import add_cache, add_quality, add_variant, settings
from pbrbench.errors import UserError


def register(sub):
    p = sub.add_parser("render", help="render scenes' ground truth (cached) with EXR + PNG previews")
    p.add_argument("scenes", nargs="*", metavar="SCENE", help="scene name, family (file stem) or path to a .toml file")
    p.add_argument("--all", action="store_true", help="render the whole scene library")
    add_quality(p)
    add_variant(p)
    add_cache(p)
    p.add_argument("--out", default=None, help="write gt.exr, gt.json (lights and camera in the camera frame, "
                   "units, noise; read both with pbrbench.io.load_render) and PNG previews here, one folder per scene")
    p.add_argument("--force", action="store_true", help="re-render even if cached")
    p.add_argument("--no-previews", action="store_true", help="skip the PNG previews")
    p.set_defaults(func=run)


RENDER_FORMAT = "pbrbench-render/1"


def describe_render(spec, gt) -> dict:
    """The JSON written beside a render's EXR: the ground truth's metadata (scene hash, quality,
    samples, seed, versions, timings, Monte Carlo noise) plus the light set and lights
    (direction toward the source in the camera frame, irradiance, positions), the camera
    (type, frame, pixel size or field of view), the units and the channel list.  Read it back
    with :func:`pbrbench.io.load_render`."""
    from pbrbench.scene.geometry import UNITS, describe_camera, describe_lights

    out = dict(gt.meta)
    res = gt.meta.get("resolution")
    if not res:
        h, w = next(iter(gt.arrays.values())).shape[:2]
        res = [w, h]
    out.update(render_format=RENDER_FORMAT, camera=describe_camera(spec, res), units=dict(UNITS),
               channels={k: list(v.shape) for k, v in sorted(gt.arrays.items())}, **describe_lights(spec))
    out["quality_figures"] = {"quality": gt.meta.get("quality"), "spp": gt.meta.get("spp"),
                              "resolution": res, "noise": gt.meta.get("noise", {})}
    out["conventions"] = ("images (H, W[, C]) linear, row 0 at the top; normals unit vectors in the camera "
                          "frame (x right, y up, z toward the camera); depth along the view axis; "
                          "lightNN.* are the images under light_set[NN] alone; *_sd the per-pixel "
                          "standard deviation of the image estimate")
    return out


def _safe(name: str) -> str:
    """A file name for a scene: its name with other characters replaced; never '', '.' or '..'
    (scene names are checked when loaded; this is the second line of defence)."""
    s = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)[:200]
    return s if s.strip(".") else "_" + s


def _write_out(gt, where: Path, d: Path, previews: bool, meta: dict | None = None) -> None:
    """Copy one ground truth into ``d`` (each file replaced atomically: whole or untouched);
    ``gt.json`` holds ``meta`` (default: the ground truth's metadata)."""
    from pbrbench.errors import disk_error
    from pbrbench.io import copy_file, write_text
    from pbrbench.render.previews import write_previews

    try:
        d.mkdir(parents=True, exist_ok=True)
        copy_file(where / "gt.exr", d / "gt.exr")
        write_text(d / "gt.json", json.dumps(gt.meta if meta is None else meta, indent=1, sort_keys=True))
        if previews:
            write_previews(gt, d)
    except OSError as exc:
        raise disk_error(exc, f"--out {d}", option="--out") from None


def run(args) -> int:
    st = settings(args)
    from pbrbench.progress import Progress
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache, ground_truth
    from pbrbench.scene.load import SceneLibrary

    if args.all and args.scenes:
        raise UserError("render: give SCENE names or --all, not both")
    if args.all:
        specs = list(SceneLibrary.from_settings(st).all().values())
        if not specs:
            raise UserError(f"render --all: the scene library {st.scenes} has no scene files")
    elif args.scenes:
        specs = SceneLibrary.from_settings(st).resolve(args.scenes)
    else:
        raise UserError("render: name at least one SCENE (see `pbrbench scenes`) or pass --all")
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise UserError(f"--out {args.out}: is a file, not a directory; choose a directory")
    quality = get_quality(args.quality)
    cache = RenderCache(st.cache)
    bars = st.progress_bars(sys.stderr)
    t_all = time.perf_counter()
    rows = []
    for spec in specs:
        t0 = time.perf_counter()
        with Progress(spec.n_passes, spec.name, bars=bars, unit="pass", lines=False) as prog:
            gt, cached = ground_truth(spec, quality, cache=cache, force=args.force,
                                      progress=lambda what, p=prog: p.update(1, what))
        dt = time.perf_counter() - t0
        where = cache.entry_dir(gt.meta["cache_key"])
        if args.out:
            d = Path(args.out) / _safe(spec.name)
            _write_out(gt, where, d, not args.no_previews, meta=describe_render(spec, gt))
            where = d
        noise = gt.meta.get("noise", {}).get("radiance_rel_sd_rms", float("nan"))
        rows.append((spec.name, "cache" if cached else f"{gt.meta['wall_s']:.1f}s", noise))
        print(f"{spec.name:44s} {'cached' if cached else 'rendered':8s} {dt:7.2f}s  noise {noise:.2e}  {where}", flush=True)
    print(f"{len(specs)} scene(s) in {time.perf_counter() - t_all:.1f}s ({args.quality}, variant {gt.meta.get('variant')})", file=sys.stderr)
    return 0
