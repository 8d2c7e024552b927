"""Inverse rendering (``nicolet2021``) against Woodham on the photometric-stereo task's own inputs.

    python scripts/inverse_targets.py --cache CACHE [--render-seed S] [--conditions local,global]
        [--scenes FOLDER] [--option refine_lit=0] [SCENE ...]

For each scene and condition: the task's ``normal_mean_deg`` (``pbrbench.metrics.normals``'s
``normal_scores``: the mean angular error over the task's evaluation domain, a pixel a method leaves
unsolved counted at 90 degrees) of ``inverse_rendering_nicolet2021`` (the standard budget, the
transport of the condition, seed 0)
and of ``woodham1980`` on the same images, the fraction of pixels the direct-light refinement
refitted, whether the fit or its start stood, and the seconds of the inverse call.  Standard
renders of ``CACHE`` at render seed ``S`` (a missing scene is rendered).  Nothing is fetched.
"""

from __future__ import annotations

import argparse
import ast
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _ps_inputs import ps_inputs  # noqa: E402

SCENES = ("ps_cup[albedo=0.9]", "ps_groove[albedo=0.9]", "ps_cap[albedo=0.9]")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--cache", required=True, help="render cache folder (standard renders)")
    ap.add_argument("--render-seed", type=int, default=0)
    ap.add_argument("--scenes", dest="library", default=None, help="scene library folder (default: pbrbench's own)")
    ap.add_argument("--conditions", default="local,local+noise0.01,global")
    ap.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                    help="an option of inverse_rendering_nicolet2021 (a Python literal), e.g. refine_lit=0")
    a = ap.parse_args(argv)
    from pbrbench.infer.photometric_stereo import METHODS
    from pbrbench.inverse.nicolet2021 import inverse_rendering_nicolet2021
    from pbrbench.metrics.normals import normal_scores
    from pbrbench.scene.load import SceneLibrary

    opts = {}
    for item in a.option:
        key, _, value = item.partition("=")
        opts[key] = ast.literal_eval(value)
    lib = SceneLibrary(a.library) if a.library else SceneLibrary()
    print(f"render seed {a.render_seed}, options {opts or 'default'}")
    print(f"{'scene':24s} {'condition':16s} {'inverse':>8s} {'woodham':>8s} {'refined':>8s} {'stood':>6s} {'s':>5s}")
    for name, cond, imgs, lights, mask, domain, n_true in ps_inputs(a.scenes, a.cache, a.conditions.split(","),
                                                                    render_seed=a.render_seed, library=lib):
        spec = lib.spec(name)
        depth = int(spec.render.max_depth) if cond.startswith("global") else 2
        t0 = time.perf_counter()
        r = inverse_rendering_nicolet2021(imgs, lights, mask=mask, scene=spec, max_depth=depth, seed=0, **opts)
        sec = time.perf_counter() - t0
        w = METHODS["woodham1980"](imgs, lights, mask=mask)
        err = [normal_scores(x.normals, n_true, domain, x.valid)[0]["normal_mean_deg"] for x in (r, w)]
        vs, ref = r.options["versus_start"], r.options["refined"]
        stood = "-" if vs is None else ("fit" if vs["kept_fit"] else "start")
        print(f"{name:24s} {cond:16s} {err[0]:8.3f} {err[1]:8.3f} {'-' if ref is None else f'{ref:.3f}':>8s} "
              f"{stood:>6s} {sec:5.0f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
