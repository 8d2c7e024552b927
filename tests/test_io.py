"""EXR I/O is bit-exact for float32 and keeps channel names; previews are 8-bit sRGB."""

from __future__ import annotations

import numpy as np
import pytest

from pbrbench.io import flatten_channels, group_channels, read_exr, srgb_encode, tonemap, write_exr


def test_exr_round_trip_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    arrays = {
        "radiance": rng.lognormal(0, 3, (17, 23, 3)).astype(np.float32),
        "normals": rng.normal(size=(17, 23, 3)).astype(np.float32),
        "depth": rng.uniform(0, 10, (17, 23)).astype(np.float32),
        "light03.direct": rng.uniform(0, 1, (17, 23, 3)).astype(np.float32),
    }
    arrays["radiance"][0, 0] = [np.finfo(np.float32).max, np.finfo(np.float32).tiny, 0.0]
    arrays["radiance"][0, 1] = [1e-45, -0.0, 65504.0]  # a denormal, negative zero, half max
    p = tmp_path / "x.exr"
    write_exr(p, arrays)
    back = read_exr(p)
    assert set(back) == set(arrays)
    for k, a in arrays.items():
        assert back[k].dtype == np.float32 and back[k].shape == a.shape
        assert back[k].tobytes() == a.tobytes(), k


def test_channel_names():
    ch = flatten_channels({"normals": np.zeros((2, 2, 3)), "radiance": np.zeros((2, 2, 3)), "mask": np.zeros((2, 2), bool)})
    assert set(ch) == {"normals.X", "normals.Y", "normals.Z", "radiance.R", "radiance.G", "radiance.B", "mask.Y"}
    assert all(v.dtype == np.float32 for v in ch.values())
    assert set(group_channels(ch)) == {"normals", "radiance", "mask"}


def test_bad_shape_is_rejected():
    with pytest.raises(ValueError, match="expected \\(H, W\\)"):
        flatten_channels({"x": np.zeros(5)})


def test_srgb_and_tonemap():
    assert srgb_encode(np.array(0.0)) == 0 and abs(srgb_encode(np.array(1.0)) - 1) < 1e-12
    assert abs(srgb_encode(np.array(0.0031308)) - 0.04045) < 1e-4  # the two pieces meet
    img = np.linspace(0, 10, 100).reshape(10, 10)
    t = tonemap(img, exposure=0.1)
    assert t.dtype == np.uint8 and t.max() == 255 and t.min() == 0
    assert np.all(np.diff(t.ravel().astype(int)) >= 0)
