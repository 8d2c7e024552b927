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


def test_srgb_encoding_is_colour_science_s_bit_for_bit():
    import colour

    x = np.concatenate([np.linspace(0.0, 1.0, 20001), np.geomspace(1e-9, 0.01, 2001), [-0.5, 1.5, np.nan]])
    ref = colour.cctf_encoding(np.clip(x, 0.0, 1.0), function="sRGB")
    np.testing.assert_array_equal(srgb_encode(x), ref)     # NaN in the same place, clipping as before


# ----------------------------------------------------------------------------- lossless PNG
def _adam7_png(path, a):
    """An interlaced PNG written by hand (filter None), for the reader's Adam7 path."""
    import struct
    import zlib

    from pbrbench.io import PNG_SIGNATURE

    h, w, ch = a.shape
    depth = 16 if a.dtype == np.uint16 else 8
    raw = b""
    for xs, ys, dx, dy in ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)):
        sub = a[ys::dy, xs::dx]
        if sub.size == 0:
            continue
        rows = (sub.astype(">u2") if depth == 16 else sub).reshape(sub.shape[0], -1).view(np.uint8)
        raw += b"".join(b"\x00" + r.tobytes() for r in rows)

    def chunk(k, d):
        return struct.pack(">I", len(d)) + k + d + struct.pack(">I", zlib.crc32(k + d) & 0xFFFFFFFF)

    ctype = {1: 0, 3: 2, 4: 6}[ch]
    path.write_bytes(PNG_SIGNATURE + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, 1))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_png_round_trip_is_lossless_for_every_filter(tmp_path, dtype, channels):
    from pbrbench.io import read_png, read_pngs, write_png_exact

    rng = np.random.default_rng(channels)
    a = rng.integers(0, np.iinfo(dtype).max, (19, 37, channels), endpoint=True).astype(dtype)
    want = a[..., 0] if channels == 1 else a
    paths = []
    for f in ((0,), (1,), (2,), (3,), (4,), (4, 0, 3, 1, 2)):
        p = tmp_path / f"f{''.join(map(str, f))}.png"
        write_png_exact(p, a, filters=f)
        paths.append(p)
        got = read_png(p)
        assert got.dtype == dtype and np.array_equal(got, want), f
    for got in read_pngs(paths):
        assert np.array_equal(got, want)


def test_png_reader_matches_pillow_8bit_and_opencv_16bit(tmp_path):
    from PIL import Image

    from pbrbench.io import read_png, write_png_exact

    rng = np.random.default_rng(3)
    a8 = rng.integers(0, 256, (21, 30, 3)).astype(np.uint8)
    Image.fromarray(a8).save(tmp_path / "pil.png", optimize=True)
    assert np.array_equal(read_png(tmp_path / "pil.png"), a8)
    Image.fromarray(a8).convert("P", palette=Image.ADAPTIVE).save(tmp_path / "pal.png")
    assert np.array_equal(read_png(tmp_path / "pal.png"), np.asarray(Image.open(tmp_path / "pal.png").convert("RGB")))
    Image.fromarray(a8[..., 0] > 128).save(tmp_path / "bits.png")                       # 1-bit
    assert np.array_equal(read_png(tmp_path / "bits.png") > 0, a8[..., 0] > 128)
    g16 = rng.integers(0, 65536, (9, 14)).astype(np.uint16)
    Image.fromarray(g16).save(tmp_path / "g16.png")
    assert np.array_equal(read_png(tmp_path / "g16.png"), g16)
    cv2 = pytest.importorskip("cv2")
    a16 = rng.integers(0, 65536, (17, 23, 3)).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "cv.png"), a16[..., ::-1])
    assert np.array_equal(read_png(tmp_path / "cv.png"), a16)
    write_png_exact(tmp_path / "mine.png", a16, filters=(4, 3))
    assert np.array_equal(cv2.imread(str(tmp_path / "mine.png"), cv2.IMREAD_UNCHANGED)[..., ::-1], a16)


@pytest.mark.parametrize("channels, dtype", [(1, np.uint8), (3, np.uint16), (4, np.uint8)])
def test_png_reader_decodes_interlaced_files(tmp_path, channels, dtype):
    from pbrbench.io import read_png

    a = np.random.default_rng(0).integers(0, np.iinfo(dtype).max, (13, 11, channels)).astype(dtype)
    _adam7_png(tmp_path / "i.png", a)
    assert np.array_equal(read_png(tmp_path / "i.png"), a[..., 0] if channels == 1 else a)


def test_damaged_pngs_are_one_line_errors_naming_the_file(tmp_path):
    from pbrbench.io import read_png, write_png_exact

    write_png_exact(tmp_path / "ok.png", np.zeros((4, 4), np.uint8))
    data = (tmp_path / "ok.png").read_bytes()
    (tmp_path / "crc.png").write_bytes(data[:-20] + bytes([data[-20] ^ 1]) + data[-19:])   # in the image data
    (tmp_path / "cut.png").write_bytes(data[:-20])
    (tmp_path / "txt.png").write_text("not a png")
    for name, msg in (("crc.png", "checksum"), ("cut.png", "[Tt]runcated"), ("txt.png", "bad signature")):
        with pytest.raises(ValueError, match=msg) as e:
            read_png(tmp_path / name)
        assert str(tmp_path / name) in str(e.value) and "\n" not in str(e.value)


def test_read_image_by_suffix_and_plain_exr(tmp_path):
    from pbrbench.io import read_image, write_exr_image

    rgb = np.random.default_rng(0).random((5, 6, 3)).astype(np.float32)
    write_exr_image(tmp_path / "a.exr", rgb)
    assert np.array_equal(read_image(tmp_path / "a.exr"), rgb)
    write_exr_image(tmp_path / "g.exr", rgb[..., 0])
    assert np.array_equal(read_image(tmp_path / "g.exr"), rgb[..., 0])
    np.save(tmp_path / "a.npy", rgb.astype(np.float64))
    assert read_image(tmp_path / "a.npy").dtype == np.float64
    write_exr(tmp_path / "gt.exr", {"radiance": rgb, "depth": rgb[..., 0]})
    with pytest.raises(ValueError, match="2 layers"):
        read_image(tmp_path / "gt.exr")
    with pytest.raises(ValueError, match="no such file"):
        read_image(tmp_path / "none.exr")
    with pytest.raises(ValueError, match="unknown image format"):
        (tmp_path / "x.foo").write_text("")
        read_image(tmp_path / "x.foo")


# ----------------------------------------------------------------------------- renders
def test_render_json_has_lights_camera_units_and_loads_back(tmp_path):
    import json

    from pbrbench.cli.render import describe_render
    from pbrbench.io import load_render
    from pbrbench.render.groundtruth import GroundTruth
    from pbrbench.scene.geometry import light_vectors
    from pbrbench.scene.load import resolve

    spec = resolve(["sphere_5lights"])[0]
    h, w = 12, 16
    arrays = {"radiance": np.ones((h, w, 3), np.float32), "mask": np.ones((h, w), np.float32),
              **{f"light{k:02d}.radiance": np.full((h, w, 3), k, np.float32) for k in range(len(spec.light_set))}}
    gt = GroundTruth(arrays, {"scene": spec.name, "resolution": [w, h], "quality": "draft", "spp": 4,
                              "noise": {"radiance_rel_sd_rms": 0.01}})
    d = tmp_path / "sphere"
    d.mkdir()
    write_exr(d / "gt.exr", arrays)
    (d / "gt.json").write_text(json.dumps(describe_render(spec, gt)))
    r = load_render(d)
    assert np.array_equal(r.light_vectors, light_vectors(spec))         # the tasks' own light vectors
    assert len(r.lights) == len(spec.light_set) and r.light_stack().shape == (len(spec.light_set), h, w, 3)
    for li, vec in zip(r.lights, r.light_vectors, strict=True):
        assert np.allclose(np.asarray(li["direction"]) * li["irradiance"], vec)
        assert abs(np.linalg.norm(li["direction"]) - 1) < 1e-12
    cam = r.camera
    assert cam["type"] == spec.camera.type and cam["resolution"] == [w, h]
    if cam["type"] == "orthographic":
        assert cam["pixel_size"] == pytest.approx(2 * spec.camera.half_width / w)
    assert "W m^-2" in r.meta["units"]["irradiance"] and r.meta["quality_figures"]["noise"]["radiance_rel_sd_rms"] == 0.01
    assert r.meta["channels"]["radiance"] == [h, w, 3] and r.mask.all()
    with pytest.raises(ValueError, match="gt.exr: missing; pass a folder written by `pbrbench render"):
        load_render(tmp_path)
