"""Exposure brackets on disk: times files in four layouts, EXIF times, one-line errors, and
`pbrbench infer hdr`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pbrbench.cli.main import main
from pbrbench.datasets import load_bracket
from pbrbench.datasets.bracket import parse_time
from pbrbench.errors import UserError
from tests.datasets.layouts import bracket

TIMES = (1 / 250, 1 / 60, 1 / 15, 1 / 4, 1.0)


@pytest.mark.parametrize("layout", ["times", "named", "opencv", "hdrshop"])
def test_every_times_layout_gives_the_same_sorted_bracket(tmp_path, layout):
    bracket(tmp_path / "b", layout=layout)
    b = load_bracket(tmp_path / "b")
    assert np.allclose(b.exposure_times, TIMES, rtol=1e-12) and np.all(np.diff(b.exposure_times) > 0)
    assert [f.name for f in b.files] == [f"exp_{i:02d}.png" for i in range(5)]
    assert b.images.dtype == np.uint8 and b.images.shape == (5, 24, 24, 3)
    assert b.images[0].mean() < b.images[-1].mean()


def test_exif_exposure_times(tmp_path):
    from PIL import Image

    d = tmp_path / "jpg"
    d.mkdir()
    for i, t in enumerate(TIMES[:3]):
        im = Image.fromarray(np.full((8, 8, 3), 40 * (i + 1), np.uint8))
        exif = Image.Exif()
        exif[0x829A] = t
        im.save(d / f"IMG_{i}.jpg", exif=exif)
    b = load_bracket(d)
    assert np.allclose(b.exposure_times, TIMES[:3], rtol=1e-6) and b.source == "EXIF ExposureTime"


def test_times_parse():
    assert parse_time("1/250", "x") == 1 / 250 and parse_time("0.5s", "x") == 0.5
    with pytest.raises(UserError, match="not an exposure time"):
        parse_time("fast", "times.txt, line 2")
    with pytest.raises(UserError, match="must be positive"):
        parse_time("0", "x")


@pytest.mark.parametrize("damage, message", [
    (lambda d: (d / "times.txt").unlink(), "no EXIF exposure time in exp_00.png"),
    (lambda d: (d / "times.txt").write_text("1/250\n1/60\n"), "2 times for 5 images"),
    (lambda d: (d / "times.txt").write_text("1/250\n1/60\n1/60\n1/4\n1\n"), "share the exposure time"),
    (lambda d: (d / "times.txt").write_text("1/250\n1/60\nsoon\n1/4\n1\n"), "times.txt, line 3: 'soon'"),
    (lambda d: np.save(d / "exp_02.npy", np.zeros(3)) or (d / "exp_02.png").unlink(), "lists|times for"),
])
def test_a_malformed_bracket_is_a_one_line_error(tmp_path, damage, message):
    d = tmp_path / "b"
    bracket(d)
    damage(d)
    with pytest.raises(UserError, match=message) as e:
        load_bracket(d)
    assert "\n" not in str(e.value)


def test_infer_hdr_merges_the_bracket(tmp_path, capsys):
    from pbrbench.io import read_image

    rad, _ = bracket(tmp_path / "b")
    assert main(["infer", "hdr", str(tmp_path / "b"), "--out", str(tmp_path / "out"), "--method", "robertson2003"]) == 0
    est = read_image(tmp_path / "out" / "radiance.exr").astype(float)
    # linear up to one scale: log radiance matches the truth's after removing the mean
    lr = np.log(est[..., 1]) - np.log(rad[..., 1])
    assert np.std(lr - lr.mean()) < 0.1
    lines = (tmp_path / "out" / "response.csv").read_text().splitlines()
    assert lines[0].startswith("level,inverse_c0") and len(lines) == 257
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert res["method"] == "robertson2003" and np.allclose(res["exposure_times"], TIMES)
    assert main(["infer", "hdr", str(tmp_path / "nothing"), "--out", str(tmp_path / "o2")]) == 1
    assert "no such folder" in capsys.readouterr().err
