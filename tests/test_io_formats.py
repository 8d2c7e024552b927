"""The image readers on every format they take, and on hostile files.

PNG values are compared with the decoder pbrbench used before it read PNGs through Pillow (a
copy kept here, and only here, as the reference), so no score can change with the library.
"""

from __future__ import annotations

import struct
import time
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest

from pbrbench import io

# ----------------------------------------------------------------------------- the old decoder
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def _png_chunks(path) -> tuple[dict, bytes, bytes | None, bytes | None]:
    import struct
    import zlib

    data = Path(path).read_bytes()
    if data[:8] != PNG_SIGNATURE:
        raise ValueError(f"{path}: not a PNG file (bad signature)")
    pos, hdr, idat, plte, trns = 8, None, [], None, None
    while pos + 8 <= len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + n]
        if len(body) < n or pos + 12 + n > len(data):
            raise ValueError(f"{path}: truncated PNG ({kind.decode('latin-1')} chunk cut short)")
        (crc,) = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError(f"{path}: corrupt PNG (CRC mismatch in the {kind.decode('latin-1')} chunk)")
        pos += 12 + n
        if kind == b"IHDR":
            w, h, depth, ctype, comp, filt, inter = struct.unpack(">IIBBBBB", body)
            if ctype not in _PNG_CHANNELS or comp != 0 or filt != 0 or inter not in (0, 1):
                raise ValueError(f"{path}: unsupported PNG header (colour type {ctype}, compression {comp}, "
                                 f"filter {filt}, interlace {inter})")
            hdr = {"width": w, "height": h, "bit_depth": depth, "colour_type": ctype, "interlace": inter,
                   "channels": _PNG_CHANNELS[ctype]}
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"PLTE":
            plte = body
        elif kind == b"tRNS":
            trns = body
        elif kind == b"IEND":
            break
    if hdr is None or not idat:
        raise ValueError(f"{path}: not a complete PNG (no IHDR or IDAT chunk)")
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as e:
        raise ValueError(f"{path}: corrupt PNG image data ({e})") from None
    return hdr, raw, plte, trns


def _unfilter(rows: list[np.ndarray], bpp: int) -> list[np.ndarray]:
    """Undo the PNG scanline filters of several images of one size at once.

    ``rows``: per image, a (h, 1 + rowbytes) uint8 array (filter byte + filtered bytes).  Rows
    whose filters are all None/Sub/Up are undone row by row (vectorised along the row); Average
    and Paeth depend on the reconstructed left neighbour, so they are undone along anti-diagonals
    of pixels (every pixel of a diagonal depends only on the previous two diagonals), for all
    images together.
    """
    h, rb1 = rows[0].shape
    rb = rb1 - 1
    g = rb // bpp
    k = len(rows)
    data = np.stack(rows, axis=1)                       # (h, K, 1 + rowbytes)
    ft = data[:, :, 0]
    if ft.max(initial=0) > 4:
        raise ValueError(f"unknown PNG filter type {int(ft.max())}")
    f = data[:, :, 1:].reshape(h, k, g, bpp)
    if ft.max(initial=0) <= 2:
        out = np.empty((h, k, g, bpp), np.uint8)
        prev = np.zeros((k, g, bpp), np.uint8)
        for r in range(h):
            cur = f[r].copy()
            sub, up = ft[r] == 1, ft[r] == 2
            if sub.any():
                cur[sub] = (np.cumsum(cur[sub], axis=1, dtype=np.uint32) & 0xFF).astype(np.uint8)
            if up.any():
                cur[up] = cur[up] + prev[up]
            out[r] = cur
            prev = out[r]
        return [out[:, i].reshape(h, rb) for i in range(k)]
    n_diag = h + g - 1
    rr = np.broadcast_to(np.arange(h)[:, None], (h, g))
    dd = rr + np.arange(g)[None, :]
    fs = np.zeros((n_diag, h, k, bpp), np.uint8)        # filtered bytes, diagonal-major
    fs[dd, rr] = f.transpose(0, 2, 1, 3)
    s = np.zeros((n_diag + 2, h + 1, k, bpp), np.int16)  # reconstructed; zero borders
    is1, is2, is3, is4 = ((ft == t)[:, :, None] for t in (1, 2, 3, 4))
    for d in range(n_diag):
        r0, r1 = max(0, d - g + 1), min(h - 1, d)
        sl = slice(r0, r1 + 1)
        a = s[d + 1, r0 + 1:r1 + 2]    # left
        b = s[d + 1, r0:r1 + 1]        # up
        c = s[d, r0:r1 + 1]            # up-left
        p = a + b - c
        pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        pred = np.where(is4[sl], paeth, np.where(is3[sl], (a + b) >> 1,
                                                  np.where(is2[sl], b, np.where(is1[sl], a, 0))))
        s[d + 2, r0 + 1:r1 + 2] = (fs[d, sl] + pred) & 0xFF
    out = s[dd + 2, rr + 1].astype(np.uint8)            # (h, g, K, bpp)
    return [out[:, :, i].reshape(h, rb) for i in range(k)]


def _unpack(rows: np.ndarray, w: int, ch: int, depth: int) -> np.ndarray:
    h = rows.shape[0]
    if depth == 16:
        return rows.reshape(h, -1).view(">u2")[:, :w * ch].astype(np.uint16).reshape(h, w, ch)
    if depth == 8:
        return rows[:, :w * ch].reshape(h, w, ch)
    per = 8 // depth
    shifts = (8 - depth * (np.arange(per) + 1)).astype(np.uint8)
    vals = (rows[:, :, None] >> shifts) & ((1 << depth) - 1)
    return vals.reshape(h, -1)[:, :w * ch].reshape(h, w, ch).astype(np.uint8)


def _decode(hdr, raw: bytes) -> np.ndarray:
    w, h, depth, ch = hdr["width"], hdr["height"], hdr["bit_depth"], hdr["channels"]
    bpp = max(1, ch * depth // 8)
    buf = np.frombuffer(raw, np.uint8)
    dtype = np.uint16 if depth == 16 else np.uint8
    if not hdr["interlace"]:
        rb = (w * ch * depth + 7) // 8
        if buf.size < h * (rb + 1):
            raise ValueError("truncated PNG image data")
        rows = _unfilter([buf[:h * (rb + 1)].reshape(h, rb + 1)], bpp)[0]
        return _unpack(rows, w, ch, depth)
    out = np.zeros((h, w, ch), dtype)
    pos = 0
    for xs, ys, dx, dy in _ADAM7:
        pw, ph = (w - xs + dx - 1) // dx, (h - ys + dy - 1) // dy
        if pw <= 0 or ph <= 0:
            continue
        rb = (pw * ch * depth + 7) // 8
        n = ph * (rb + 1)
        if buf.size < pos + n:
            raise ValueError("truncated PNG image data")
        rows = _unfilter([buf[pos:pos + n].reshape(ph, rb + 1)], bpp)[0]
        out[ys::dy, xs::dx] = _unpack(rows, pw, ch, depth)
        pos += n
    return out


def _expand(hdr, a: np.ndarray, plte, trns, path) -> np.ndarray:
    if hdr["colour_type"] == 3:
        if plte is None:
            raise ValueError(f"{path}: palette PNG without a PLTE chunk")
        pal = np.frombuffer(plte, np.uint8).reshape(-1, 3)
        idx = a[..., 0].astype(np.intp)
        if idx.max(initial=0) >= len(pal):
            raise ValueError(f"{path}: palette index {int(idx.max())} beyond the {len(pal)} palette entries")
        rgb = pal[idx]
        if trns is not None:
            alpha = np.full(len(pal), 255, np.uint8)
            t = np.frombuffer(trns, np.uint8)[:len(pal)]
            alpha[:len(t)] = t
            rgb = np.concatenate([rgb, alpha[idx][..., None]], axis=-1)
        return rgb
    return a[..., 0] if a.shape[-1] == 1 else a


def legacy_read_png(path) -> np.ndarray:
    hdr, raw, plte, trns = _png_chunks(path)
    return _expand(hdr, _decode(hdr, raw), plte, trns, path)


# ----------------------------------------------------------------------------- PNG, bit-exact
def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def _png_files(d: Path) -> list[Path]:
    """8/16-bit grey, grey + alpha, RGB, RGBA (every filter), palette (1/2/4/8 bits, with and
    without tRNS), 1/2/4-bit grey, interlaced: written by Pillow and by write_png_exact."""
    from PIL import Image

    from tests.test_io import _adam7_png

    rng = np.random.default_rng(7)
    out = []
    for ch in (1, 2, 3, 4):
        for dt in (np.uint8, np.uint16):
            for f in ((0,), (1,), (2,), (3,), (4,), (4, 0, 3, 1, 2)):
                a = rng.integers(0, np.iinfo(dt).max, (19, 37, ch), endpoint=True).astype(dt)
                p = d / f"e{ch}{np.dtype(dt).itemsize}_{''.join(map(str, f))}.png"
                io.write_png_exact(p, a, filters=f)
                out.append(p)
            if ch in (1, 3, 4):
                p = d / f"i{ch}{np.dtype(dt).itemsize}.png"
                _adam7_png(p, rng.integers(0, np.iinfo(dt).max, (13, 11, ch), endpoint=True).astype(dt))
                out.append(p)
    rgb = rng.integers(0, 256, (21, 30, 3)).astype(np.uint8)
    for colors, bits in ((2, 1), (4, 2), (16, 4), (256, 8)):
        im = Image.fromarray(rgb).convert("P", palette=Image.Palette.ADAPTIVE, colors=colors)
        im.save(d / f"p{bits}.png", bits=bits)
        im.save(d / f"pt{bits}.png", bits=bits, transparency=bytes([0, 128, 255][:colors]))
        out += [d / f"p{bits}.png", d / f"pt{bits}.png"]
    im.save(d / "pt_one.png", transparency=3)
    for bits in (1, 2, 4):
        Image.fromarray((rgb[..., 0] >> (8 - bits)) * (255 // (2**bits - 1))).save(d / f"g{bits}.png", bits=bits)
    Image.fromarray(rgb).save(d / "rgb_key.png", transparency=(1, 2, 3))
    Image.fromarray(rng.integers(0, 65536, (9, 14)).astype(np.uint16)).save(d / "pil16.png")
    out += [d / "pt_one.png", d / "g1.png", d / "g2.png", d / "g4.png", d / "rgb_key.png", d / "pil16.png"]
    return out


def test_png_values_are_those_of_the_old_decoder(tmp_path):
    files = _png_files(tmp_path)
    kinds = set()
    for p in files:
        want, got = legacy_read_png(p), io.read_png(p)
        assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want), p.name
        kinds.add((got.dtype.itemsize, got.shape[2] if got.ndim == 3 else 1))
    assert kinds == {(1, 1), (1, 2), (1, 3), (1, 4), (2, 1), (2, 2), (2, 3), (2, 4)}
    assert io.read_png(tmp_path / "g2.png").max() == 3 and io.read_png(tmp_path / "pt2.png").shape[2] == 4


def test_png_of_the_repository_read_as_before():
    root = Path(__file__).resolve().parents[1]
    pngs = [p for p in root.rglob("*.png") if ".venv" not in p.parts and ".git" not in p.parts][:40]
    for p in pngs:
        assert np.array_equal(io.read_png(p), legacy_read_png(p)), p


def test_16bit_png_written_by_another_program_is_exact(tmp_path):
    cv2 = pytest.importorskip("cv2")
    a = np.random.default_rng(1).integers(0, 65536, (17, 23, 3)).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "cv.png"), a[..., ::-1])
    assert np.array_equal(io.read_image(tmp_path / "cv.png"), a)


# ----------------------------------------------------------------------------- other formats
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("channels", [1, 3, 4])
def test_tiff_is_exact(tmp_path, dtype, channels):
    rng = np.random.default_rng(channels)
    a = (rng.random((9, 13, channels)) * 60000).astype(dtype)
    a = a[..., 0] if channels == 1 else a
    io.write_image(tmp_path / "a.tif", a)
    got = io.read_image(tmp_path / "a.tif")
    assert got.dtype == dtype and np.array_equal(got, a)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_tga_is_exact(tmp_path, channels):
    from PIL import Image

    a = np.random.default_rng(2).integers(0, 256, (11, 7, channels)).astype(np.uint8)
    a = a[..., 0] if channels == 1 else a
    Image.fromarray(a).save(tmp_path / "a.tga")
    assert np.array_equal(io.read_image(tmp_path / "a.tga"), a)
    io.write_image(tmp_path / "b.tga", a)
    assert np.array_equal(io.read_image(tmp_path / "b.tga"), a)


def test_jpeg_reads_as_pillow_decodes_it(tmp_path):
    from PIL import Image

    yy, xx = np.mgrid[0:16, 0:24]
    a = np.stack([xx * 10, yy * 15, xx + yy + 40], axis=-1).astype(np.uint8)
    Image.fromarray(a).save(tmp_path / "a.jpg", quality=95)
    got = io.read_image(tmp_path / "a.jpg")
    assert got.dtype == np.uint8 and got.shape == a.shape
    assert np.array_equal(got, np.asarray(Image.open(tmp_path / "a.jpg")))
    assert np.abs(got.astype(int) - a).mean() < 4          # lossy, but the same picture


def test_pfm_reads_bottom_up_and_checks_its_header(tmp_path):
    a = np.random.default_rng(4).random((5, 6, 3)).astype(np.float32)
    (tmp_path / "a.pfm").write_bytes(b"PF\n6 5\n-1.0\n" + a[::-1].astype("<f4").tobytes())
    assert np.array_equal(io.read_image(tmp_path / "a.pfm"), a)
    (tmp_path / "cut.pfm").write_bytes(b"PF\n6 5\n-1.0\n" + a.tobytes()[:50])
    (tmp_path / "huge.pfm").write_bytes(b"PF\n100000 100000\n-1.0\n" + bytes(64))
    (tmp_path / "bad.pfm").write_bytes(b"PF\nsix five\n-1.0\n")
    for name, msg in (("cut", "truncated"), ("huge", "256.00 MiB"), ("bad", "damaged PFM header")):
        with pytest.raises(ValueError, match=msg) as e:
            io.read_image(tmp_path / f"{name}.pfm")
        assert str(tmp_path / f"{name}.pfm") in str(e.value) and "\n" not in str(e.value)


def test_npy_goes_through_the_header_checks(tmp_path):
    np.save(tmp_path / "ok.npy", np.arange(6.0).reshape(2, 3))
    assert np.array_equal(io.read_image(tmp_path / "ok.npy"), np.arange(6.0).reshape(2, 3))
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with open(tmp_path / "huge.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (10**5, 10**5)})
    (tmp_path / "cut.npy").write_bytes((tmp_path / "ok.npy").read_bytes()[:-8])
    for name, msg in (("obj", "never unpickles"), ("huge", "above the 256.00 MiB"), ("cut", "truncated")):
        with pytest.raises(ValueError, match=msg) as e:
            io.read_image(tmp_path / f"{name}.npy")
        assert str(tmp_path / f"{name}.npy") in str(e.value) and "\n" not in str(e.value)


def test_the_limit_is_the_scene_data_limit():
    from pbrbench.scene.data import MAX_DATA_BYTES

    assert io.MAX_IMAGE_BYTES == MAX_DATA_BYTES


# ----------------------------------------------------------------------------- hostile files
def _bomb(path: Path, w: int, h: int, depth: int, ctype: int) -> None:
    """A PNG declaring w x h pixels whose data is a few kilobytes of zlib'd zeros."""
    path.write_bytes(io.PNG_SIGNATURE + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, 0))
                     + _chunk(b"IDAT", zlib.compress(bytes(2**20), 9)) + _chunk(b"IEND", b""))


@pytest.mark.parametrize("w, h, depth, ctype", [(100_000, 100_000, 16, 6), (20_000, 20_000, 8, 0),
                                                (12_000, 12_000, 16, 2), (9_000, 9_000, 8, 3)])
def test_a_png_bomb_is_refused_quickly_before_allocating(tmp_path, w, h, depth, ctype):
    from pbrbench.datasets.files import load_image
    from pbrbench.errors import UserError

    p = tmp_path / "bomb.png"
    _bomb(p, w, h, depth, ctype)
    tracemalloc.start()
    t = time.perf_counter()
    try:
        with pytest.raises(ValueError, match="its header announces .* above the 256") as e:
            io.read_image(p)
        took, peak = time.perf_counter() - t, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert took < 1.0 and peak < 2**22, (took, peak)
    assert str(p) in str(e.value) and "\n" not in str(e.value) and "crop / downsample" in str(e.value)
    with pytest.raises(UserError, match="bomb.png: ") as e:
        load_image(p)
    assert "\n" not in str(e.value)


def test_png_with_endless_image_data_decodes_only_what_it_declares(tmp_path):
    rows = b"".join(b"\0" + bytes(16) for _ in range(8))
    co = zlib.compressobj(9)
    data = co.compress(rows) + b"".join(co.compress(bytes(2**24)) for _ in range(16)) + co.flush()   # 256 MiB more
    p = tmp_path / "long.png"
    p.write_bytes(io.PNG_SIGNATURE + _chunk(b"IHDR", struct.pack(">IIBBBBB", 16, 8, 8, 0, 0, 0, 0))
                  + _chunk(b"IDAT", data) + _chunk(b"IEND", b""))
    tracemalloc.start()
    try:
        a = io.read_image(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert a.shape == (8, 16) and not a.any() and peak < 2**23


def test_tiff_and_pillow_formats_refuse_huge_headers(tmp_path):
    import tifffile
    from PIL import Image

    tifffile.imwrite(tmp_path / "huge.tif", np.zeros((4, 4, 3), np.uint16), photometric="rgb")
    with tifffile.TiffFile(tmp_path / "huge.tif", mode="r+b") as tf:    # declares 40000^2 x 3 x 2 bytes
        tf.pages[0].tags["ImageWidth"].overwrite(40_000)
        tf.pages[0].tags["ImageLength"].overwrite(40_000)
    Image.new("L", (4, 4)).save(tmp_path / "small.tga")
    data = bytearray((tmp_path / "small.tga").read_bytes())
    data[12:16] = struct.pack("<HH", 60_000, 60_000)              # TGA width / height
    (tmp_path / "huge.tga").write_bytes(bytes(data))
    for name in ("huge.tif", "huge.tga"):
        t = time.perf_counter()
        with pytest.raises(ValueError, match="its header announces") as e:
            io.read_image(tmp_path / name)
        assert time.perf_counter() - t < 1.0 and str(tmp_path / name) in str(e.value) and "\n" not in str(e.value)


def test_a_damaged_exr_is_one_line_and_prints_nothing(tmp_path, capfd):
    from pbrbench.datasets.files import load_image
    from pbrbench.errors import UserError

    io.write_exr_image(tmp_path / "a.exr", np.random.default_rng(0).random((64, 64, 3)).astype(np.float32))
    data = (tmp_path / "a.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[:len(data) // 2])
    (tmp_path / "junk.exr").write_bytes(b"v/1\x01" + bytes(100))
    capfd.readouterr()
    for name in ("cut.exr", "junk.exr"):
        for read in (io.read_image, io.read_exr):
            with pytest.raises(ValueError, match="not a readable EXR file") as e:
                read(tmp_path / name)
            assert str(e.value).startswith(str(tmp_path / name)) and "\n" not in str(e.value)
        with pytest.raises(UserError) as e:
            load_image(tmp_path / name)
        assert "\n" not in str(e.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_an_exr_header_above_the_limit_is_refused(tmp_path, monkeypatch):
    io.write_exr_image(tmp_path / "a.exr", np.zeros((64, 64, 3), np.float32))
    with pytest.raises(ValueError, match="64 x 64 x 3 samples .* above the 16.00 KiB"):
        monkeypatch.setattr("pbrbench.io.exr.MAX_IMAGE_BYTES", 2**14)
        io.read_exr_image(tmp_path / "a.exr")
