"""Renderer speed: LLVM vs scalar on a direct-lit sphere, and the library at a quality preset.

Each variant runs in its own subprocess (a process can hold only one Mitsuba variant).
``python -m pbrbench.perf.render``.
"""

from __future__ import annotations

import json
import subprocess
import sys

from pbrbench.perf import row

PROBE = r"""
import json, sys, time
import numpy as np
from pbrbench.render.variant import mitsuba
mi = mitsuba(sys.argv[1])
T = mi.ScalarTransform4f
res, spp = int(sys.argv[2]), int(sys.argv[3])
scene = mi.load_dict({"type": "scene", "integrator": {"type": "direct"},
    "sensor": {"type": "orthographic", "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]) @ T().scale([1.05, 1.05, 1]),
               "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
               "sampler": {"type": "multijitter", "sample_count": spp}},
    "ball": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.7}}},
    "sun": {"type": "directional", "direction": [-0.3, -0.2, -1.0], "irradiance": {"type": "rgb", "value": 3.0}}})
np.array(mi.render(scene, seed=0))  # warm-up (JIT compile in LLVM)
walls, cpus = [], []
for k in range(5):
    t, c = time.perf_counter(), time.process_time()
    np.array(mi.render(scene, seed=k + 1))
    walls.append(time.perf_counter() - t); cpus.append(time.process_time() - c)
print(json.dumps({"wall": float(np.median(walls)), "cpu": float(np.median(cpus))}))
"""


def time_variant(variant: str, res: int = 256, spp: int = 16) -> dict:
    r = subprocess.run([sys.executable, "-c", PROBE, variant, str(res), str(spp)], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(f"{variant} render probe failed: {r.stderr[-500:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def run(quick: bool = False) -> list[dict]:
    res, spp = (128, 16) if quick else (256, 16)
    out = []
    times = {}
    for v in ("llvm_ad_rgb", "scalar_rgb"):
        try:
            times[v] = time_variant(v, res, spp)
        except RuntimeError as exc:
            print(f"skipping {v}: {exc}", file=sys.stderr)
            continue
        case = f"sphere {res}px {spp}spp direct"
        out.append(row("render", case, v, "wall", times[v]["wall"], "s", better="lower"))
        out.append(row("render", case, v, "cpu", times[v]["cpu"], "s", better="lower"))
    if len(times) == 2:
        out.append(row("render", f"sphere {res}px {spp}spp direct", "llvm/scalar", "speedup_wall",
                       times["scalar_rgb"]["wall"] / times["llvm_ad_rgb"]["wall"], "x", better="higher"))
    return out


def main(argv=None) -> None:
    from pbrbench.perf import main_for

    main_for(run, argv)


if __name__ == "__main__":
    main()
