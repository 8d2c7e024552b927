"""Safe variant selection: never pick a libLLVM < 16 (it aborts the process), fall back cleanly."""

from __future__ import annotations

import glob
import json
import os
import subprocess
import sys

import pytest

from pbrbench.render.variant import MIN_LLVM, find_llvm, llvm_major, llvm_major_from_name

PROBE = r"""
import json, os, sys
from pbrbench.render import variant
from pbrbench.render.variant import choose_variant
from pbrbench.settings import Settings
variant.configure(Settings.from_env())      # as the command line does, once
c = choose_variant()
out = {"variant": c.variant, "llvm": c.llvm_path, "notice": c.notice, "env": os.environ.get("DRJIT_LIBLLVM_PATH")}
if len(sys.argv) > 1:  # render a tiny scene with the chosen variant: must not abort
    import numpy as np
    import mitsuba as mi
    mi.set_variant(c.variant)
    s = mi.load_dict({"type": "scene", "i": {"type": "direct"}, "s": {"type": "sphere"}, "l": {"type": "directional", "direction": [0, 0, -1]},
                      "c": {"type": "orthographic", "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                            "film": {"type": "hdrfilm", "width": 8, "height": 8}}})
    out["mean"] = float(np.array(mi.render(s, spp=4)).mean())
print(json.dumps(out))
"""


def run_probe(env_update: dict, render: bool = False) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("DRJIT_LIBLLVM_PATH", "PBRBENCH_VARIANT", "PBRBENCH_LLVM_SEARCH")}
    env.update(env_update)
    env["PBRBENCH_NO_CUDA"] = "1"
    args = [sys.executable, "-c", PROBE] + (["render"] if render else [])
    r = subprocess.run(args, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, f"probe died (rc={r.returncode}): {r.stderr[-2000:]}"
    return json.loads(r.stdout.strip().splitlines()[-1])


OLD = sorted(p for p in glob.glob("/usr/lib/*/libLLVM-1[45]*.so*") if os.path.isfile(p))


def test_version_from_file_name():
    assert llvm_major_from_name("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15
    assert llvm_major_from_name("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert llvm_major_from_name("/usr/lib/x86_64-linux-gnu/libLLVM-14.0.6.so.1") == 14
    assert llvm_major("/no/such/libLLVM-19.so") is None


@pytest.mark.render
def test_missing_path_falls_back_and_renders():
    out = run_probe({"DRJIT_LIBLLVM_PATH": "/no/such/libLLVM-19.so.1"}, render=True)
    assert out["notice"] and "/no/such/libLLVM-19.so.1" in out["notice"]
    assert out["variant"] in ("llvm_ad_rgb", "scalar_rgb")
    assert out["env"] != "/no/such/libLLVM-19.so.1"
    assert out["mean"] > 0


@pytest.mark.render
@pytest.mark.skipif(not OLD, reason="no libLLVM 14/15 on this machine to refuse")
def test_old_llvm_is_refused_and_fallback_to_newer():
    out = run_probe({"DRJIT_LIBLLVM_PATH": OLD[-1]}, render=True)
    assert out["llvm"] != OLD[-1] and out["env"] != OLD[-1]
    assert "older than" in out["notice"]
    best, _ = find_llvm()
    assert out["variant"] == ("llvm_ad_rgb" if best else "scalar_rgb")
    assert out["mean"] > 0  # the process survived a render


@pytest.mark.render
@pytest.mark.skipif(not OLD, reason="no libLLVM 14/15 on this machine to refuse")
def test_only_old_llvm_falls_back_to_scalar_with_notice():
    # search only the directory of the old library and hide the good ones: the chooser must
    # refuse LLVM 14/15 and choose scalar_rgb, and rendering must still work
    d = "/tmp/pbrbench-old-llvm-only"
    os.makedirs(d, exist_ok=True)
    link = os.path.join(d, os.path.basename(OLD[-1]))
    if not os.path.lexists(link):
        os.symlink(OLD[-1], link)
    out = run_probe({"DRJIT_LIBLLVM_PATH": OLD[-1], "PBRBENCH_LLVM_SEARCH": d}, render=True)
    assert out["variant"] == "scalar_rgb"
    assert out["llvm"] is None
    assert "scalar_rgb" in out["notice"]
    assert out["mean"] > 0


def test_explicit_variant_wins():
    out = run_probe({"PBRBENCH_VARIANT": "scalar_rgb"})
    assert out["variant"] == "scalar_rgb"


def test_best_llvm_is_new_enough():
    best, found = find_llvm()
    if best is None:
        pytest.skip("no libLLVM >= 16 installed (set-up installs libllvm19 as root)")
    assert llvm_major(best) >= MIN_LLVM
    assert all(v is None or v < MIN_LLVM or v <= llvm_major(best) for _, v in found)


def test_known_variants_are_read_even_after_mitsuba_is_imported():
    # once imported, sys.modules["mitsuba"] is mitsuba's variant alias module (no package folder);
    # the variants still come from the installed package's config.py
    import mitsuba  # noqa: F401

    from pbrbench.render.variant import known_variants

    v = known_variants()
    assert v and "scalar_rgb" in v
