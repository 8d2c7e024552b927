"""The psmImages layout: TGA images, lights.txt (with or without a count line and intensities),
a mask image; photometric stereo on it recovers the known normals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from pbrbench.cli.main import main
from pbrbench.datasets import is_diligent, is_psm, load_psm
from pbrbench.errors import UserError
from pbrbench.shading.surfaces import on_grid
from tests.datasets.layouts import DIRS


def psm_object(root, name="buddha", *, size=40, intensities=None, count_line=True, lights_above=True):
    """A Lambertian sphere in the psmImages layout (8-bit TGA); returns (normals, mask, 8-bit images)."""
    folder = root / name
    folder.mkdir(parents=True)
    s = on_grid("sphere", size, 1.05)
    n, mask = s.normals, s.mask
    ints = np.ones(len(DIRS)) if intensities is None else np.asarray(intensities, float)
    shade = np.clip(np.einsum("hwc,kc->khw", n, DIRS), 0, None) * mask * ints[:, None, None]
    imgs = np.clip(np.round(shade[..., None] * np.array([200.0, 150.0, 100.0])), 0, 255).astype(np.uint8)
    for k, im in enumerate(imgs):
        Image.fromarray(im).save(folder / f"{name}.{k}.tga")
    Image.fromarray(mask.astype(np.uint8) * 255).save(folder / f"{name}.mask.tga")
    rows = [" ".join(f"{v:.6f}" for v in d) + (f" {i:.4f}" if intensities is not None else "") for d, i in zip(DIRS, ints, strict=True)]
    text = (f"{len(DIRS)}\n" if count_line else "") + "\n".join(rows) + "\n"
    (root if lights_above else folder).joinpath("lights.txt").write_text(text)
    return n, mask, imgs


@pytest.mark.parametrize("count_line, lights_above, with_intensities", [(True, True, False), (False, False, True)])
def test_a_psm_folder_loads_in_order(tmp_path, count_line, lights_above, with_intensities):
    ints = np.linspace(0.7, 1.3, len(DIRS)) if with_intensities else None
    n, mask, imgs = psm_object(tmp_path, count_line=count_line, lights_above=lights_above, intensities=ints)
    d = tmp_path / "buddha"
    assert is_psm(d) and not is_diligent(d)
    obj = load_psm(d)
    assert obj.images.shape == (len(DIRS), *mask.shape, 3) and obj.normals is None
    assert np.allclose(obj.lights, DIRS) and np.array_equal(obj.mask, mask)
    want = imgs / 255.0 / (np.round(ints, 4) if ints is not None else np.ones(len(DIRS)))[:, None, None, None]
    assert np.array_equal(obj.images, want)                                # buddha.10.tga after buddha.9.tga
    assert [f.name for f in obj.files][9:11] == ["buddha.9.tga", "buddha.10.tga"]


def test_infer_recovers_the_normals_of_a_psm_folder(tmp_path, capsys):
    from pbrbench.io import read_image

    n, mask, _ = psm_object(tmp_path, size=48)
    d = tmp_path / "buddha"
    assert main(["infer", "photometric-stereo", str(d), "--out", str(tmp_path / "out")]) == 0
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert res["layout"] == "psmImages layout" and res["images"] == len(DIRS)
    est = read_image(tmp_path / "out" / "normals.exr").astype(np.float64)
    inner = mask & (n[..., 2] > 0.3)                 # lit by every light: 8-bit rounding the only error
    err = np.degrees(np.arccos(np.clip((est * n).sum(-1)[inner], -1, 1)))
    assert err.mean() < 1.0 and np.percentile(err, 95) < 2.5


@pytest.mark.parametrize("damage, message", [
    (lambda d: (d.parent / "lights.txt").write_text("12\n0 0 1\n"), r"lights.txt: the first line announces 12 lights, the file lists 1"),
    (lambda d: (d.parent / "lights.txt").write_text("0 0 1\n" * 11), r"lights.txt: 11 lights for 12 images"),
    (lambda d: (d.parent / "lights.txt").write_text("0 0 one\n" * 12), r"lights.txt, light 1: .* not a row of numbers"),
    (lambda d: (d.parent / "lights.txt").write_text("0 0 0\n" * 12), r"light 1 has a zero direction"),
    (lambda d: (d.parent / "lights.txt").write_text("0 0 1 -1\n" * 12), r"not positive"),
    (lambda d: (d / "buddha.3.tga").write_bytes(b"junk"), r"buddha.3.tga: "),
    (lambda d: (d / "buddha.mask.tga").write_bytes(b"junk"), r"buddha.mask.tga: "),
])
def test_a_malformed_psm_folder_is_a_one_line_error(tmp_path, damage, message):
    psm_object(tmp_path, size=16)
    d = tmp_path / "buddha"
    damage(d)
    with pytest.raises(UserError, match=message) as e:
        load_psm(d)
    assert "\n" not in str(e.value)


def test_a_folder_that_is_no_layout_names_all_three(tmp_path, capsys):
    (tmp_path / "x").mkdir()
    assert main(["infer", "photometric-stereo", str(tmp_path / "x"), "--out", str(tmp_path / "o")]) == 1
    assert "psmImages object folder" in capsys.readouterr().err
