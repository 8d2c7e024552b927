"""The render cache and the atomic writers under faults, without rendering: a write that fails
or does not read back leaves no entry and raises one line naming the cache; an atomic write that
fails leaves the previous file whole and no temporary behind."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from pbrbench import io as pio
from pbrbench.errors import DiskError
from pbrbench.render import cache as C
from pbrbench.render.groundtruth import GroundTruth


def _gt():
    rng = np.random.default_rng(0)
    return GroundTruth({"radiance": rng.random((8, 8, 3), dtype=np.float32), "mask": np.ones((8, 8), np.float32)},
                       {"scene": "t", "noise": {}})


def test_put_and_get_round_trip(tmp_path):
    c = C.RenderCache(tmp_path)
    c.put("ab" * 32, _gt())
    got = c.get("ab" * 32)
    assert got is not None and got["radiance"].tobytes() == _gt()["radiance"].tobytes()


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES])
def test_a_failing_write_leaves_no_entry(tmp_path, monkeypatch, code):
    def failing(path, arrays, header=None):
        with open(path, "wb") as f:
            f.write(b"\x76\x2f\x31\x01 partial")
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(C, "write_exr", failing)
    c = C.RenderCache(tmp_path)
    with pytest.raises(DiskError, match=rf"render cache {tmp_path}.*{os.strerror(code)}") as e:
        c.put("cd" * 32, _gt())
    assert "\n" not in str(e.value)
    assert c.info()["entries"] == 0 and c.info()["stale_temporaries"] == 0 and c.get("cd" * 32) is None


def test_an_exr_that_does_not_read_back_is_not_cached(tmp_path, monkeypatch):
    real = C.write_exr

    def wrong(path, arrays, header=None):  # a silent corruption: other values than were rendered
        real(path, {k: v + 1 for k, v in arrays.items()}, header)

    monkeypatch.setattr(C, "write_exr", wrong)
    c = C.RenderCache(tmp_path)
    with pytest.raises(DiskError, match="does not read back identically"):
        c.put("ef" * 32, _gt())
    assert c.info()["entries"] == 0


def test_cache_root_that_is_a_file(tmp_path):
    f = tmp_path / "cache"
    f.write_text("x")
    with pytest.raises(DiskError, match="is a file, not a directory"):
        C.RenderCache(f).info()
    with pytest.raises(DiskError, match="Not a directory"):
        C.RenderCache(f).put("01" * 32, _gt())


@pytest.mark.parametrize("writer", ["text", "bytes", "copy", "exr", "png"])
def test_atomic_writers_keep_the_old_file_on_failure(tmp_path, monkeypatch, writer):
    target = tmp_path / f"out.{ {'exr': 'exr', 'png': 'png'}.get(writer, 'txt') }"
    src = tmp_path / "src.txt"
    src.write_text("new content")
    write = {"text": lambda: pio.write_text(target, "new content"), "bytes": lambda: pio.write_bytes(target, b"new"),
             "copy": lambda: pio.copy_file(src, target),
             "exr": lambda: pio.write_exr(target, {"a": np.zeros((4, 4), np.float32)}),
             "png": lambda: pio.write_png(target, np.zeros((4, 4, 3), np.uint8))}[writer]
    write()
    old = target.read_bytes()

    def full(a, b):
        raise OSError(errno.ENOSPC, "No space left on device", str(b))

    monkeypatch.setattr(os, "replace", full)
    with pytest.raises(OSError, match="No space left"):
        write()
    assert target.read_bytes() == old
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".tmp-")] == []
