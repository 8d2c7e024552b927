"""Render cache: content addressing, atomic writes (SIGKILL mid-write), corrupt entries ignored."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pbrbench.quality import DRAFT, STANDARD
from pbrbench.render.cache import RenderCache, cache_key, ground_truth
from pbrbench.scene.spec import SceneSpec

SCENE = {
    "name": "cache_probe",
    "description": "tiny lit sphere",
    "camera": {"half_width": 1.1},
    "render": {"resolution": 16, "spp": 8},
    "shapes": [{"type": "sphere", "name": "ball"}],
    "lights": [{"type": "directional", "direction": [0, 0, 1], "irradiance": 3.0}],
}


def spec(**upd) -> SceneSpec:
    return SceneSpec.model_validate({**SCENE, **upd})


def test_key_depends_on_content_quality_variant():
    a = cache_key(spec(), DRAFT, "llvm_ad_rgb")
    assert a == cache_key(spec(), DRAFT, "llvm_ad_rgb")
    assert a != cache_key(spec(), STANDARD, "llvm_ad_rgb")
    assert a != cache_key(spec(), DRAFT, "scalar_rgb")
    assert a != cache_key(spec(render={"resolution": 16, "spp": 8, "seed": 1}), DRAFT, "llvm_ad_rgb")
    # the description does not change the render, so it does not change the key
    assert a == cache_key(spec(description="another text"), DRAFT, "llvm_ad_rgb")


@pytest.mark.render
def test_round_trip_through_cache(tmp_path):
    c = RenderCache(tmp_path)
    gt, cached = ground_truth(spec(), STANDARD, cache=c)
    assert not cached
    gt2, cached2 = ground_truth(spec(), STANDARD, cache=c)
    assert cached2
    for k in gt.arrays:
        assert gt2.arrays[k].tobytes() == gt.arrays[k].tobytes(), k
    assert gt2.meta["scene_hash"] == spec().content_hash()
    for key in ("variant", "spp", "seed", "versions", "wall_s", "cpu_s", "noise", "quality"):
        assert key in gt2.meta
    assert c.info()["entries"] == 1


@pytest.mark.render
def test_corrupt_entry_is_not_read(tmp_path):
    c = RenderCache(tmp_path)
    gt, _ = ground_truth(spec(), STANDARD, cache=c)
    exr = c.entry_dir(gt.meta["cache_key"]) / "gt.exr"
    data = bytearray(exr.read_bytes())
    data[len(data) // 2] ^= 0xFF
    exr.write_bytes(bytes(data))
    assert c.get(gt.meta["cache_key"]) is None  # checksum mismatch -> discarded
    assert not exr.exists()
    _, cached = ground_truth(spec(), STANDARD, cache=c)
    assert not cached


KILLED_WRITER = textwrap.dedent("""
    import sys, time
    import pbrbench.render.cache as C
    from pbrbench.scene.spec import SceneSpec
    real = C.write_exr
    def slow_write(path, arrays, header=None):
        real(path, arrays, header)
        with open(path, "r+b") as f:      # leave a half-written file behind
            f.truncate(f.seek(0, 2) // 2)
        print("WRITING", flush=True)
        time.sleep(60)
    C.write_exr = slow_write
    spec = SceneSpec.model_validate(__SCENE__)
    from pbrbench.quality import STANDARD
    C.ground_truth(spec, STANDARD, cache=C.RenderCache(sys.argv[1]))
""").replace("__SCENE__", repr(SCENE))


@pytest.mark.render
def test_sigkill_mid_write_leaves_no_valid_entry(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", KILLED_WRITER, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert "WRITING" in line, "the writer never reached the EXR write"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    c = RenderCache(tmp_path)
    key = cache_key(spec(), STANDARD, _variant())
    assert c.get(key) is None
    assert c.info()["entries"] == 0 and c.info()["stale_temporaries"] == 1
    gt, cached = ground_truth(spec(), STANDARD, cache=c)  # the rerun succeeds
    assert not cached and np.isfinite(gt["radiance"]).all() and gt["radiance"].max() > 0
    assert c.get(key) is not None
    assert c.clear() == 1 and c.info()["stale_temporaries"] == 0


def _variant():
    from pbrbench.render.variant import choose_variant, current_choice

    ch = current_choice() or choose_variant()
    return ch.variant


@pytest.mark.render
@pytest.mark.parametrize("action", ["info", "clear"])
def test_cache_cli(tmp_path, capsys, monkeypatch, action):
    from pbrbench.cli.main import main

    monkeypatch.setenv("PBRBENCH_CACHE", str(tmp_path))  # restored after the test

    ground_truth(spec(), STANDARD, cache=RenderCache(tmp_path))
    assert main(["cache", action, "--cache", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert ("entries  1" in out) if action == "info" else ("removed 1 entries" in out)


def test_black_ground_truth_is_refused_unless_every_visible_surface_is_black():
    from pbrbench.errors import UserError
    from pbrbench.render.cache import check_ground_truth
    from pbrbench.render.groundtruth import GroundTruth

    cov = np.ones((4, 4), np.float32)
    zero = np.zeros((4, 4, 3), np.float32)
    black = GroundTruth({"radiance": zero, "coverage": cov, "albedo": zero}, {})
    check_ground_truth(spec(), black)  # albedo 0 everywhere seen: black is the right answer
    grey = GroundTruth({"radiance": zero, "coverage": cov, "albedo": zero + 0.5}, {})
    with pytest.raises(UserError, match="no light reaches the visible surfaces"):
        check_ground_truth(spec(), grey)
    nothing = GroundTruth({"radiance": zero, "coverage": 0 * cov, "albedo": zero}, {})
    with pytest.raises(UserError, match="sees no geometry"):
        check_ground_truth(spec(), nothing)
